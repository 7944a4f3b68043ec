"""Unified walk–fall–getup task: the env the student is distilled in (training/distill/dagger.py default) and
fine-tuned in (distill/finetune.py).

The seed's student learns the whole task, so one episode mixes what the two experts do: full-body collision;
the getup tasks' fallen / kneeling / standing starts (getup_base.GetupStarts); the joystick env's commands,
pushes and reward terms (walking.Walking, a base of both); 1000-step episodes that end only on non-finite
physics (the student must get up); actor observation TERMS_UNION (82). Ours, off by default: knockdown.prob of
the pushes are as hard as the loop's push test (knockdown.KNOCKDOWN_MPS, or knockdown.shove "torso": the test's
own torso shove), and walls.prob of the episodes walk into the low-wall course (wall_course.py) at a held
forward command.

Reward (reward.mode), per control step × ctrl_dt:
* "monitor" (default; brax bc ignores it, it only makes DAgger's eval curves mean something):
  alive + w_height·HO(standing targets) + standing·(w_lin·tracking_lin_vel + w_ang·tracking_ang_vel), standing =
  waist at or above the teacher's switch height (0.5 m).
* "skills" (the fine-tune): each expert's own reward where it is in charge. Below the switch
  reward.getup.scale × the getup expert's reward, its gated Height, Pose and energy terms weighted by
  reward.getup.scales as the getup task's reward.scales weigh them; at or above it the joystick
  env's terms × reward.joystick_scales (clipped at 0) + the most the scaled getup reward can pay below (the
  standing bonus); − reward.getup.failed_rise_cost per failed attempt (events.py). With
  reward.walk_after_stand_up the walk pays only after the getup's stand-up (events.py: standing held
  STAND_HOLD_S); reward.course.progress_weight [1/m] pays the metres credited in wall-course episodes
  (wall_course.credited_progress: new ground along +x, at most at the held command).
Why the scale, the bonus and the course term (ours; figures in LESSONS, "Design figures"): unscaled, or without
the bonus, the switch would be a wall to stay below; banked ground pays a fall across a wall through the getup
beyond it, where a cost on standing still charged the getup as much as the stall. Metrics "wall_course" (1 per
step of a course episode; the BC term reads it) and "course_progress_m".
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
from ml_collections import config_dict
from mujoco_playground._src import mjx_env

from common import observation as obsdef
from messages.contract import WAIST_SWITCH_HEIGHT_M
from training.envs import base, starts, wall_course
from training.envs import getup_rewards as G
from training.envs import joystick_rewards as R
from training.envs.getup import default_config as getup_config
from training.envs.getup_base import START_KINDS, GetupStarts
from training.envs.joystick import default_config as joystick_config
from training.envs.starts import knockdown
from training.envs.starts.bank import place
from training.envs.starts.push import TorsoShove
from training.envs.walking import Walking

METRIC_NAMES = ("reward/alive", "reward/height", "reward/tracking_lin_vel", "reward/tracking_ang_vel",
                "standing")
SKILLS_METRIC_NAMES = ("reward/getup", "reward/joystick", "failed_rises", "gate", "standing", "wall_course",
                       "course_progress_m")
REWARD_MODES = ("monitor", "skills")


def default_config() -> config_dict.ConfigDict:
    getup, joy = getup_config(), joystick_config()
    cfg = base.base_config()
    cfg.collision = "full_body"
    cfg.episode_length = 1000
    cfg.obs_terms = [list(t) for t in obsdef.TERMS_UNION]
    cfg.action_scale = getup.action_scale   # the wider map: the student must reach both experts' targets
    # Starts: the getup expert's full-task settings; commands / pushes: the joystick expert's. Copied from
    # their configs (not restated) so the three tasks cannot drift apart.
    cfg.start_probs = list(getup.start_probs)
    cfg.standing_targets_m = list(getup.standing_targets_m)
    cfg.command_resample_steps = joy.command_resample_steps
    cfg.zero_command_prob = joy.zero_command_prob
    cfg.push = config_dict.create(**joy.push.to_dict())
    # knockdown.prob of the pushes are knockdowns (module docstring). shove "velocity": the base speed changes by
    # magnitude_range_mps in a random direction; "torso": the loop's push test itself, its torso impulse
    # forward or backward (2 : 1) off the heading (starts/push.py); "mixed": both kinds,
    # torso_share of the knockdowns the torso shove
    cfg.knockdown = config_dict.create(prob=0.0, magnitude_range_mps=list(knockdown.KNOCKDOWN_MPS), shove="velocity",
                                       torso_share=0.5)
    starts.add_config_groups(cfg, "unified")   # the getup tasks' fallen starts; walls: the course's share
    cfg.soft_joint_pos_limit_factor = joy.soft_joint_pos_limit_factor
    cfg.reward = config_dict.create(
        mode="monitor",   # or "skills" (module docstring)
        scales=config_dict.create(alive=0.25, height=1.0, tracking_lin_vel=1.0, tracking_ang_vel=0.5),
        tracking_sigma=joy.reward.tracking_sigma,
        standing_waist_height_m=WAIST_SWITCH_HEIGHT_M,
        # "skills": the joystick env's terms and scales above the switch, the getup expert's below it
        max_foot_height_m=joy.reward.max_foot_height_m,
        joystick_scales=config_dict.create(**joy.reward.scales.to_dict()),
        # "skills": below the switch the getup expert's terms, weighted by scales (getup_knockdown's own
        # reward.scales), the sum × scale (docstring)
        getup=config_dict.create(scale=0.02, scales=config_dict.create(height=1.0, pose=1.0, energy=-0.01),
                                 failed_rise_cost=0.0),
        course=config_dict.create(progress_weight=0.0),   # [1/m] of credited progress (docstring); 0: off
        walk_after_stand_up=False)   # the walk's reward waits for the getup's stand-up (docstring)
    return cfg


class Unified(GetupStarts, Walking):
    """Getup starts + joystick commands and pushes on the full-body model; actor obs TERMS_UNION."""

    SHOVES = ("velocity", "torso", "mixed")   # knockdown.shove

    def _wall_share(self) -> float:
        return float(self._config.walls.prob)

    def has_wall_course(self) -> bool:
        return super().has_wall_course() or self._wall_share() > 0

    def __init__(self, config: config_dict.ConfigDict | None = None, config_overrides: dict | None = None,
                 make_env=None):
        super().__init__(config if config is not None else default_config(), config_overrides, make_env)
        kd = self._config.knockdown
        if not (0.0 <= kd.prob <= 1.0 and 0.0 <= kd.magnitude_range_mps[0] <= kd.magnitude_range_mps[1]):
            raise ValueError(f"knockdown: prob must be in [0, 1] and magnitude_range_mps an ordered pair of speeds "
                             f"[m/s] >= 0, got {kd.prob} and {list(kd.magnitude_range_mps)}")
        if not 0.0 <= self._wall_share() <= 1.0:
            raise ValueError(f"walls.prob must be in [0, 1], got {self._wall_share()}")
        shove = kd.shove
        if shove not in self.SHOVES:
            raise ValueError(f"knockdown.shove {shove!r}: one of {', '.join(self.SHOVES)}")
        self._reward_mode = self._config.reward.mode
        if self._reward_mode not in REWARD_MODES:
            raise ValueError(f"reward.mode {self._reward_mode!r}: one of {', '.join(REWARD_MODES)}")
        if self._reward_mode == "skills":
            self._init_reward_constants()
            self._progress_weight = self._config.reward.course.progress_weight
            self._walk_after_stand_up = bool(self._config.reward.walk_after_stand_up)
            g = self._config.reward.getup
            if not (g.scale > 0 and g.scales.height >= 0 and g.scales.pose >= 0 and g.scales.energy <= 0):
                raise ValueError(f"reward.getup: scale must be > 0, scales.height and scales.pose >= 0 and "
                                 f"scales.energy <= 0 (a cost), got {g.scale}, {g.scales.height}, {g.scales.pose} "
                                 f"and {g.scales.energy}")
        # the share of knockdowns that are torso shoves
        self._torso_share = {"velocity": 0.0, "torso": 1.0}.get(shove, float(kd.torso_share))
        if not 0.0 <= self._torso_share <= 1.0:
            raise ValueError(f"knockdown.torso_share must be in [0, 1], got {self._torso_share}")
        self._torso_shove = TorsoShove(self._mj_model, self._home_qpos) if self._torso_share > 0 else None

    def reset(self, rng: jax.Array) -> mjx_env.State:
        rng, k_start, k_cmd, k_push, k_obs, k_start_course = jax.random.split(rng, 6)
        qpos, qvel, kind = self._start_state(k_start)
        command = self.sample_command(k_cmd)
        course = jnp.zeros((), bool)
        if self._wall_share() > 0:   # the course's start only where walls are drawn (its keys always are)
            k_course, k_approach = jax.random.split(k_start_course, 2)
            course = jax.random.bernoulli(k_course, self._wall_share())
            xy, yaw, course_command = wall_course.course_start(k_approach, self._config.wall_course)
            standing_qpos, standing_qvel = place(self._home_qpos, jnp.zeros_like(qvel), xy, yaw)
            qpos, qvel = jnp.where(course, standing_qpos, qpos), jnp.where(course, standing_qvel, qvel)
            kind = jnp.where(course, START_KINDS.index("standing"), kind)
            command = jnp.where(course, course_command, command)
        data = self.make_data(qpos, qvel)
        info = {
            "rng": rng,
            "command": command,
            "course": course,
            "command_step": jnp.array(0, jnp.int32),
            "last_act": jnp.zeros(base.NUM_JOINTS),
            "phase": obsdef.initial_gait_phase(jnp).astype(jnp.float32),
            "push": jnp.zeros(2),
            "push_step": jnp.array(0, jnp.int32),
            "push_interval_steps": self._push_interval_steps(k_push),
            "start_kind": kind.astype(jnp.int32),
            "runtime_target": self.start_target(qpos),
            **self.body_readings(data),
        }
        if self._reward_mode == "skills":
            info.update(self.initial_feet_info(), rise_track=G.rise_track_start(info["trunk_height"]),
                        course_best_x=qpos[0], course_credit_x=qpos[0])   # [m]: nothing banked at the start
        obs = self._observe(data, info, k_obs)
        names = SKILLS_METRIC_NAMES if self._reward_mode == "skills" else METRIC_NAMES
        metrics = {k: jnp.zeros(()) for k in names}
        return mjx_env.State(data, obs, jnp.zeros(()), jnp.zeros(()), metrics, info)

    def step(self, state: mjx_env.State, action: jax.Array) -> mjx_env.State:
        action = self.full_action(action)
        info = dict(state.info)
        info["rng"], k_theta, k_mag, k_cmd, k_obs = jax.random.split(info["rng"], 5)
        data = self._apply_push(state.data, info, k_theta, k_mag)
        data, info["runtime_target"] = self.physics_step(data, self.motor_targets(action), info["runtime_target"])
        info.update(self.body_readings(data))
        if self._reward_mode == "skills":
            reward, terms = self._skills_reward(data, action, info)
        else:
            scaled, standing = self._monitor_terms(data, info)
            reward = sum(scaled.values()) * self.dt
            terms = {**{f"reward/{k}": v for k, v in scaled.items()}, "standing": standing}

        course_command = info["command"]
        self._advance_clock_and_command(info, action, k_cmd)     # same tick bookkeeping as the joystick env
        info["command"] = jnp.where(info["course"], course_command, info["command"])   # a wall approach holds it

        obs = self._observe(data, info, k_obs)
        metrics = dict(state.metrics)   # keep what wrappers added (brax's EvalWrapper adds "reward")
        metrics.update({k: v.astype(jnp.float32) for k, v in terms.items()})
        done = self.invalid(data).astype(jnp.float32)  # falls do not end the episode
        return state.replace(data=data, obs=obs, reward=reward, done=done, metrics=metrics, info=info)

    def _apply_push(self, data, info, k_theta, k_mag):
        """The joystick env's push (with knockdown.shove "velocity", knockdown.prob of them knockdowns); with
        "torso", that share of the pushes is instead the loop's push-test shove ("mixed": torso_share of it)."""
        if self._torso_shove is None:
            return super()._apply_push(data, info, k_theta, k_mag)
        k_pick, k_walk, k_shove = jax.random.split(k_mag, 3)
        due = jnp.mod(info["push_step"] + 1, info["push_interval_steps"]) == 0
        walked = super()._apply_push(data, info, k_theta, k_walk)   # counts the push step, sets info["push"]
        shove_prob = self._config.knockdown.prob * self._torso_share
        shoved = due & jax.random.bernoulli(k_pick, shove_prob) & bool(self._config.push.enable)
        dqvel = self._torso_shove.dqvel(data.qpos, k_shove)
        info["push"] = jnp.where(shoved, dqvel[:2], info["push"])
        return data.replace(qvel=jnp.where(shoved, data.qvel + dqvel, walked.qvel))

    def _push_magnitude(self, rng):
        """A joystick-env push [m/s], or with probability knockdown.prob (× the share that are not torso shoves,
        _apply_push) a knockdown (module docstring)."""
        k_walk, k_hard, k_pick = jax.random.split(rng, 3)
        if self._torso_share == 1.0:
            return super()._push_magnitude(k_walk)
        kd = self._config.knockdown
        hard = jax.random.uniform(k_hard, minval=kd.magnitude_range_mps[0], maxval=kd.magnitude_range_mps[1])
        knocked = jax.random.bernoulli(k_pick, kd.prob * (1.0 - self._torso_share))
        return jnp.where(knocked, hard, super()._push_magnitude(k_walk))

    def _skills_reward(self, data, action, info):
        """The "skills" reward of the state after the step (module docstring) and its metrics; advances the
        feet and failed-rise bookkeeping in info (in place)."""
        cfg = self._config.reward
        contact, first_contact = self._feet_touchdown(data, info)
        standing = info["waist_height"] >= cfg.standing_waist_height_m
        walk = self._scaled_reward_terms(cfg.joystick_scales, data, action, info, first_contact, contact)
        w = cfg.getup.scales
        joystick = jnp.maximum(sum(walk.values()), 0.0) + cfg.getup.scale * G.gated_reward_max(w.height, w.pose)
        gate = G.gate(info["trunk_height"], info["up_z"])
        height, pose = self.gated_rewards(data.qpos[7:], info, gate)
        getup = cfg.getup.scale * (w.height * height + w.pose * pose + w.energy * self.energy_cost(data))
        info["rise_track"], failed = G.rise_track_step(info["rise_track"], info["trunk_height"], self.standing(info),
                                                       self._stand_hold_ticks)
        if self._walk_after_stand_up:
            standing = standing & ~info["rise_track"]["down"]
        self._feet_after_step(info, contact)
        info["course_best_x"], info["course_credit_x"], gained = wall_course.credited_progress(
            info["course_best_x"], info["course_credit_x"], data.qpos[0], info["command"][0], self.dt)
        progress = info["course"] * gained
        reward = (jnp.where(standing, joystick, getup) * self.dt - cfg.getup.failed_rise_cost * failed
                  + self._progress_weight * progress)
        return reward, {"reward/getup": jnp.where(standing, 0.0, getup),
                        "reward/joystick": jnp.where(standing, joystick, 0.0),
                        "failed_rises": failed, "gate": gate, "standing": standing, "wall_course": info["course"],
                        "course_progress_m": progress}

    def _monitor_terms(self, data, info):
        """The "monitor" reward: (scaled terms, standing flag) for the state after the step."""
        cfg = self._config.reward
        w = cfg.scales
        cmd = info["command"]
        standing = info["waist_height"] >= cfg.standing_waist_height_m
        lin = R.tracking_lin_vel(cmd, self.sensor(data, "local_linvel"), cfg.tracking_sigma)
        ang = R.tracking_ang_vel(cmd, self.sensor(data, "gyro"), cfg.tracking_sigma)
        scaled = {"alive": w.alive * R.alive(),
                  "height": w.height * self.height_orientation(info, self._standing_targets),
                  "tracking_lin_vel": w.tracking_lin_vel * lin * standing,
                  "tracking_ang_vel": w.tracking_ang_vel * ang * standing}
        return scaled, standing

    def _observe(self, data, info, rng) -> dict[str, jax.Array]:
        s = self.observation_state(data, info["command"], info["last_act"], info["phase"])
        noisy, clean = self.actor_observation(s, rng, self._config.noise.level)
        privileged = jnp.concatenate([self.privileged_base(data, clean), data.site_xpos[self._feet_sites].ravel()])
        return {"state": noisy, "privileged_state": privileged}

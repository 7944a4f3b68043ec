"""What the getup tasks share, one file per task over it (thesis §4.4–4.8, the keyframe curriculum and its
baseline): getup_kneel.py (fallen → kneel), getup_stand.py (kneel → stand), getup.py (the gated full task),
getup_baseline.py (the reward-only baseline).

`GetupStarts`: the model (full-body collision), the fallen / kneeling / standing starts (config.start_probs) and
the targets the getup rewards read; the unified env starts its episodes the same way. `GetupTask`: one reset
and one step for the four tasks. A task names its reward terms (getup_rewards.py) in its `_reward_terms`, and
its config weights them by `reward.scales`; the step sums the scaled terms × ctrl_dt and logs each as
`reward/<name>`, as the joystick env does. Per control step every task also reports the gate (§4.8, the task's
`_gate_state`), its first hold (`gate_reached`), failed rises (getup_rewards.rise_track_step), `success` (the
task's `_success`; standing by common/events.py unless the task says otherwise) and success split by start
kind; episodes end on non-finite physics or the task's `_terminated`. Actor obs = Table 4.2, TERMS_GETUP (52),
noise U(−1, 1)·obs_noise_scale on every entry (§4.6); critic extras: the gate state and ‖u − e_z‖.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from ml_collections import config_dict
from mujoco_playground._src import mjx_env

from common import observation as obsdef
from common.events import STAND_HOLD_S, STANDING_TRUNK_THRESHOLD_M, UPRIGHT_UP_Z
from messages import contract
from training.envs import base, starts
from training.envs import getup_rewards as G
from training.envs.starts.fallen import fallen_states, weight_sides

GETUP_ACTION_SCALE_RAD = 2.0    # rad per unit action (base_config says why)
START_KINDS = ("fallen", "kneeling", "standing")


def base_config() -> config_dict.ConfigDict:
    """Settings every getup task shares; a task's config is a diff of this (its starts and reward scales)."""
    cfg = base.base_config()
    cfg.collision = "full_body"
    # ±0.5 rad around home (the joystick's scale) cannot even reach the kneel keyframe (knee 1.9 rad vs
    # home 0.4). 2 rad per unit puts the kneel at |a| ≈ 0.75, off tanh saturation; base.py caps it per joint
    # at the joint's range.
    cfg.action_scale = GETUP_ACTION_SCALE_RAD
    cfg.episode_length = 500
    cfg.obs_terms = [list(t) for t in obsdef.TERMS_GETUP]
    cfg.obs_noise_scale = 0.0            # U(−1, 1)·this per observation entry; 0 = off (seed's fine-tune: 1)
    cfg.start_probs = [1.0, 0.0, 0.0]    # (fallen, kneeling, standing)
    # (torso, waist) heights the Height Reward wants once the kneel gate holds [m]
    cfg.standing_targets_m = [contract.STANDING_TARGET_TRUNK_M, contract.STANDING_TARGET_WAIST_M]
    return cfg


class GetupStarts(base.T1Env):
    """Fallen / kneeling / standing starts and the getup rewards' targets (the getup tasks, the unified env)."""

    def __init__(self, config: config_dict.ConfigDict, config_overrides: dict | None = None, make_env=None):
        super().__init__(config, config_overrides, make_env)
        cfg = self._config
        probs = jnp.asarray(list(cfg.start_probs), dtype=jnp.float32)
        if probs.shape != (3,) or bool(jnp.any(probs < 0)) or abs(float(probs.sum()) - 1.0) > 1e-6:
            raise ValueError(f"start_probs must be 3 non-negative numbers summing to 1 "
                             f"(fallen, kneeling, standing), got {list(cfg.start_probs)}")
        self._start_logits = jnp.log(probs)
        if float(probs[0]) > 0:
            qpos, qvel = weight_sides(*self.fallen_starts(int(cfg.fallen.bank_starts), int(cfg.fallen.seed)),
                                      cfg.fallen.side_weights)
        else:  # no fallen starts: skip the host precomputation
            qpos, qvel = self._home_qpos[None], jnp.zeros((1, self._mj_model.nv))
        self._fallen_qpos, self._fallen_qvel = jnp.asarray(qpos), jnp.asarray(qvel)
        # jax float32 scalars (strong types: no jit retrace)
        self._kneel_targets = jnp.asarray(self._keyframe_heights(self._kneel_qpos), jnp.float32)
        self._standing_targets = jnp.asarray(cfg.standing_targets_m, jnp.float32)
        self._stand_hold_ticks = int(round(STAND_HOLD_S / self.dt))

    def fallen_starts(self, num: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
        """(qpos, qvel) of this env's fallen starts for seeds seed … seed + num − 1 (training and evaluation):
        after the runtime's PREPARE ramp, under this env's supervisor settings."""
        return fallen_states(num, seed, float(self._config.fallen.prepare_s), self.host_supervisor())

    def host_supervisor(self) -> tuple[float, float]:
        """Rule R6 as the host rollouts of the start banks take it: (max target speed [rad/s], range fraction)."""
        step_per_substep, fraction = self._supervisor_settings(self._config)
        return step_per_substep / float(self._config.sim_dt), fraction

    def start_probabilities(self) -> list[float]:
        return list(self._config.start_probs)

    def _keyframe_heights(self, qpos) -> tuple[float, float]:
        """(trunk, waist) origin heights [m] of a keyframe, from the model's kinematics."""
        data = mujoco.MjData(self._mj_model)
        data.qpos[:] = np.asarray(qpos)
        mujoco.mj_kinematics(self._mj_model, data)
        return float(data.xpos[self._trunk_id, 2]), float(data.xpos[self._waist_id, 2])

    def height_orientation(self, info, targets):
        return G.height_orientation_reward(info["trunk_height"], info["waist_height"], info["up_z"],
                                           targets[0], targets[1])

    def gated_rewards(self, q, info, gate):
        """(Height, Pose) Rewards of the full task (§4.8) at joint angles q [rad] under `gate`."""
        kneel_h = self.height_orientation(info, self._kneel_targets)
        stand_h = self.height_orientation(info, self._standing_targets)
        kneel_p, stand_p = G.pose_reward(q, self._kneel_qpos[7:]), G.pose_reward(q, self._default_pose)
        return G.gated_height_reward(gate, kneel_h, stand_h), G.gated_pose_reward(gate, kneel_p, stand_p)

    @staticmethod
    def standing(info):
        return (info["trunk_height"] >= STANDING_TRUNK_THRESHOLD_M) & (info["up_z"] >= UPRIGHT_UP_Z)

    def energy_cost(self, data):
        """§4.7's energy cost Σ|v·τ/τmax| of the state after the step (before its weight)."""
        return G.energy_cost(data.qvel[6:], data.actuator_force, self._tau_limit)

    def _start_state(self, rng):
        """(qpos, qvel, kind index) of a random start."""
        k_kind, k_idx = jax.random.split(rng)
        kind = jax.random.categorical(k_kind, self._start_logits)
        idx = jax.random.randint(k_idx, (), 0, self._fallen_qpos.shape[0])
        qpos = jnp.stack([self._fallen_qpos[idx], self._kneel_qpos, self._home_qpos])[kind]
        qvel = jnp.stack([self._fallen_qvel[idx], jnp.zeros_like(self._fallen_qvel[0]),
                          jnp.zeros_like(self._fallen_qvel[0])])[kind]
        return qpos, qvel, kind


class GetupTask(GetupStarts):
    """Reset, step, observation and bookkeeping of a getup task (module docstring); a task adds its terms."""

    def __init__(self, config: config_dict.ConfigDict, config_overrides: dict | None = None, make_env=None):
        super().__init__(config, config_overrides, make_env)
        # seed §4.6: the same U(−1, 1) range on every entry, whatever its unit (base.py scales per term)
        self._noise_scale = jnp.ones_like(self._noise_scale)
        self._scales = {k: float(v) for k, v in self._config.reward.scales.items()}
        self._fallen_banks = [(prob, tuple(jnp.asarray(x) for x in bank))
                              for prob, bank in starts.fallen_share_banks(self, self._config)]

    # ------------------------------------------------------------------ what a task defines
    def _reward_terms(self, data, info) -> dict[str, jax.Array]:
        """The unscaled reward terms of the state after the step, one per key of config.reward.scales."""
        raise NotImplementedError

    def _gate_state(self, gate_now, was_on, info) -> jax.Array:
        """The gate the task carries (critic input, metric `gate`): §4.8's per-step condition."""
        return gate_now

    def _success(self, info) -> jax.Array:
        return self.standing(info)

    def _terminated(self, info) -> jax.Array:
        """Episode ends besides non-finite physics (none by default: the seed's getup never ends early)."""
        return jnp.zeros((), dtype=bool)

    def _task_info(self, info, data) -> dict:
        """The task's own per-episode state: its entries at the reset (info holds `bank_row`) and after each
        step (data after it; the entries the task added before it). None by default."""
        return {}

    def _critic_extras(self, info) -> list[jax.Array]:
        """The critic's inputs beyond the gate state and ‖u − e_z‖ (scalars). None by default."""
        return []

    # ------------------------------------------------------------------ shared
    def metric_names(self) -> tuple[str, ...]:
        return (*(f"reward/{k}" for k in self._scales), "failed_rises", "gate", "gate_reached", "success",
                "success_from_kneel", "success_from_fallen")

    def success_from(self, kind: str, success, info):
        """`success` counted only in episodes that started as START_KINDS' `kind`."""
        return success * (info["start_kind"] == START_KINDS.index(kind))

    def _start_state(self, rng):
        """(qpos, qvel, kind, bank row) of the task's start; with start banks (starts/), a share of the fallen ones
        from those banks, `bank row` its row in the banks' rows in order (−1: not from a bank)."""
        none = jnp.asarray(-1, jnp.int32)
        if not self._fallen_banks:
            return *super()._start_state(rng), none
        k_start, k_use, k_idx = jax.random.split(rng, 3)
        qpos, qvel, kind = super()._start_state(k_start)
        u, lo, row, offset = jax.random.uniform(k_use), 0.0, none, 0
        for prob, (bank_qpos, bank_qvel) in self._fallen_banks:   # each bank its slice of [0, 1)
            use = (kind == 0) & (u >= lo) & (u < lo + prob)
            idx = jax.random.randint(k_idx, (), 0, bank_qpos.shape[0])
            qpos, qvel = jnp.where(use, bank_qpos[idx], qpos), jnp.where(use, bank_qvel[idx], qvel)
            row = jnp.where(use, offset + idx, row)
            lo, offset = lo + prob, offset + bank_qpos.shape[0]
        return qpos, qvel, kind, row

    def _start_info(self, rng, data, kind, bank_row) -> dict:
        info = {"rng": rng, "last_act": jnp.zeros(base.NUM_JOINTS), "start_kind": kind.astype(jnp.int32),
                "runtime_target": self.start_target(data.qpos), "up": self.up_vector(data),
                "bank_row": bank_row, **self.body_readings(data)}
        off = jnp.zeros((), dtype=bool)
        info["gate"] = self._gate_state(G.gate(info["trunk_height"], info["up_z"]), off, info)
        info["gate_met"] = off              # §4.8's gate has held at a step since the reset
        info["rise_track"] = G.rise_track_start(info["trunk_height"])
        return {**info, **self._task_info(info, data)}

    def _observe(self, data, info, rng) -> dict[str, jax.Array]:
        s = self.observation_state(data, jnp.zeros(3), info["last_act"], obsdef.initial_gait_phase(jnp))
        noisy, clean = self.actor_observation(s, rng, self._config.obs_noise_scale)
        extra = jnp.stack([info["gate"].astype(jnp.float32), G.up_error(info["up"]), *self._critic_extras(info)])
        return {"state": noisy, "privileged_state": jnp.concatenate([self.privileged_base(data, clean), extra])}

    def reset(self, rng: jax.Array) -> mjx_env.State:
        rng, k_start, k_obs = jax.random.split(rng, 3)
        qpos, qvel, kind, bank_row = self._start_state(k_start)
        data = self.make_data(qpos, qvel)
        info = self._start_info(rng, data, kind, bank_row)
        obs = self._observe(data, info, k_obs)
        metrics = {k: jnp.zeros(()) for k in self.metric_names()}
        return mjx_env.State(data, obs, jnp.zeros(()), jnp.zeros(()), metrics, info)

    def step(self, state: mjx_env.State, action: jax.Array) -> mjx_env.State:
        action = self.full_action(action)
        info = dict(state.info)
        info["rng"], k_obs = jax.random.split(info["rng"])
        data, info["runtime_target"] = self.physics_step(state.data, self.motor_targets(action),
                                                         info["runtime_target"])
        info.update(self.body_readings(data))
        info["up"] = self.up_vector(data)
        gate_now = G.gate(info["trunk_height"], info["up_z"])
        info["gate"] = self._gate_state(gate_now, state.info["gate"], info)
        info["gate_met"] = state.info["gate_met"] | gate_now
        info.update(self._task_info(info, data))
        scaled = {k: v * self._scales[k] for k, v in self._reward_terms(data, info).items()}
        reward = sum(scaled.values()) * self.dt
        info["rise_track"], failed = G.rise_track_step(state.info["rise_track"], info["trunk_height"],
                                                       self.standing(info), self._stand_hold_ticks)
        info["last_act"] = action
        obs = self._observe(data, info, k_obs)
        success = self._success(info).astype(jnp.float32)
        metrics = dict(state.metrics)   # keep what wrappers added (brax's EvalWrapper adds "reward")
        metrics.update({f"reward/{k}": v.astype(jnp.float32) for k, v in scaled.items()})
        metrics.update({
            "gate": info["gate"].astype(jnp.float32),
            # 1 at the first step the gate holds: an episode's sum is whether it met the gate
            "gate_reached": (gate_now & ~state.info["gate_met"]).astype(jnp.float32),
            "failed_rises": failed.astype(jnp.float32), "success": success,
            "success_from_kneel": self.success_from("kneeling", success, info),
            "success_from_fallen": self.success_from("fallen", success, info)})
        done = self.invalid(data) | self._terminated(info)
        return state.replace(data=data, obs=obs, reward=reward, done=done.astype(jnp.float32), metrics=metrics,
                             info=info)

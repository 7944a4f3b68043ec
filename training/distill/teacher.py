"""The teachers of the distillation (training/envs/experts.py's experts): the stitched teacher of two and the
keyframe getup's latched chain of three, both a switched_teacher.

Stitched teacher (ARCHITECTURE.md, Training): the getup expert while the waist is below
WAIST_SWITCH_HEIGHT_M, else the joystick expert. Waist height is privileged (state.info["waist_height"]);
brax bc's teacher sees only observations, so distillation adds it to the observation dict under
WAIST_OBS_KEY (training/distill/dagger.py); the student's network reads only "state".
"""
from __future__ import annotations

import functools
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from common import events
from common import observation as obsdef
from messages.contract import WAIST_SWITCH_HEIGHT_M
from training import envs
from training.core import checkpoints
from training.envs.experts import STUDENT_OBS_KEY, WAIST_OBS_KEY, Expert, TermAdapter, load_expert, per_joint

STAGE_OBS_KEY = "keyframe_stage"   # the chain teacher's stage in the observation dict (the student never reads it)

CHECK_FALLEN_STARTS = 16  # host-precomputed fallen starts for the `teacher` check rollout (seconds each)


class WaistObservation:
    """Wraps a brax-training-wrapped (batched) env: adds obs[WAIST_OBS_KEY] = waist height (B, 1) [m],
    read from the physics data (so it is right after an auto-reset, when info is still the old one)."""

    def __init__(self, wrapped, base_env):
        self._env, self._waist = wrapped, jax.vmap(base_env.waist_height)

    def __getattr__(self, name):
        return getattr(self._env, name)

    def _add(self, state):
        obs = dict(state.obs)
        obs[WAIST_OBS_KEY] = self._waist(state.data)[..., None]
        return state.replace(obs=obs)

    def reset(self, rng):
        return self._add(self._env.reset(rng))

    def step(self, state, action):
        inner_obs = {k: v for k, v in state.obs.items() if k != WAIST_OBS_KEY}  # the inner env's own layout
        return self._add(self._env.step(state.replace(obs=inner_obs), action))


class KeyframeStageObservation:
    """Wraps a brax-training-wrapped (batched) getup env: adds obs[STAGE_OBS_KEY] = the keyframe chain's stage
    (B, 1) (common/events.keyframe_stage: roll → rise → stand, latched), advanced from the last step's stage by
    the physics data after each step; an episode's first stage is the start rule's, also after an auto-reset.
    handover_up_error: the rise's hand-over to the stand (keyframe_stage's; §4.8's gate by default)."""

    def __init__(self, wrapped, base_env, handover_up_error: float = events.KNEEL_GATE_UP_ERROR):
        self._env = wrapped

        def stage_after(stage, data):
            r = base_env.body_readings(data)
            spin = jnp.linalg.norm(base_env.sensor(data, "gyro"))
            return events.keyframe_stage(stage, base_env.forward_z(data), r["trunk_height"], r["up_z"], spin, jnp,
                                         handover_up_error)

        self._stage_after = jax.vmap(stage_after)

    def __getattr__(self, name):
        return getattr(self._env, name)

    def _add(self, state, stage):
        obs = dict(state.obs)
        obs[STAGE_OBS_KEY] = self._stage_after(stage, state.data)[..., None].astype(state.obs[STUDENT_OBS_KEY].dtype)
        return state.replace(obs=obs)

    def reset(self, rng):
        state = self._env.reset(rng)
        return self._add(state, jnp.full(state.done.shape, events.KEYFRAME_START, jnp.int32))

    def step(self, state, action):
        stage = state.obs[STAGE_OBS_KEY][..., 0].astype(jnp.int32)
        inner_obs = {k: v for k, v in state.obs.items() if k != STAGE_OBS_KEY}
        nxt = self._env.step(state.replace(obs=inner_obs), action)
        return self._add(nxt, jnp.where(nxt.done > 0, events.KEYFRAME_START, stage))   # an auto-reset: over


def switched_teacher(experts: Sequence[Expert], pick, student_terms: Sequence, student_action_scale):
    """brax-bc teacher: obs dict {"state": student-layout obs, plus what `pick` reads} → (action, {"loc": label})
    in the STUDENT's action map, from experts[pick(obs)] (pick: the acting expert's index, (..., 1)). The experts'
    maps differ (joystick ±0.5 rad around home, getup up to 2 rad): each expert's action is turned into the same
    joint targets in the student's map, a_s = a_e · s_e / s_s (the student's scale is at least each expert's, so
    |a_s| ≤ 1).

    The observation's last action is mapped back the same way: an expert that reads `last_action` gets
    clip(a_s · s_s / s_e, −1, 1), the previous joint targets in ITS map, so while it drives it reads its own
    previous action, as when it was trained and in the runtime (read in the student's map, the joystick
    expert would see a quarter of its own action). The clip
    matters only on the first tick after another expert or the student acted with targets outside the expert's range.

    The label is what the student must output to execute a_s. brax bc's loss is
    ‖tanh(loc_student) − tanh(label)‖², minimised at loc_student = label, and the student (no tanh squash, the
    seed's Table 5.2) acts with loc itself: label = a_s. (With atanh(a_s) it would execute atanh(a_s), e.g. 1.47
    for a teacher's 0.9, overshooting every large getup target.)"""
    adapters = [TermAdapter(student_terms, e.obs_terms) for e in experts]
    s_student = per_joint(student_action_scale)
    ratios = [e.action_scale / s_student for e in experts]
    for e, ratio in zip(experts, ratios):
        if np.any(ratio > 1.0 + 1e-6):
            raise ValueError(f"{e.name} expert's action scale exceeds the student's on some joint: the student "
                             "could not reach its targets (give the student env the larger scale)")
    last_action_at = [obsdef.term_slice(e.obs_terms, "last_action") for e in experts]

    def expert_obs(i, state):
        """The student-layout observation in expert i's layout, with its last action in the expert's map."""
        obs = adapters[i](state)
        if last_action_at[i] is None:
            return obs
        own = jnp.clip(obs[..., last_action_at[i]] / jnp.asarray(ratios[i]), -1.0, 1.0)
        return obs.at[..., last_action_at[i]].set(own)

    def teacher(obs, key=None):
        del key  # deterministic experts
        state = obs[STUDENT_OBS_KEY]
        acting = pick(obs)
        out = [jnp.tanh(e.loc(expert_obs(i, state))) * jnp.asarray(ratios[i]) for i, e in enumerate(experts)]
        action = jnp.select([acting == i for i in range(len(experts))], out)
        return action, {"loc": action}

    return teacher


def make_teacher(getup: Expert, joystick: Expert, student_terms: Sequence, student_action_scale,
                 switch_height_m: float = WAIST_SWITCH_HEIGHT_M):
    """The stitched teacher (switched_teacher): the getup expert where obs[WAIST_OBS_KEY] < switch_height_m, else
    the joystick expert."""
    return switched_teacher((getup, joystick), lambda obs: (obs[WAIST_OBS_KEY] >= switch_height_m).astype(int),
                            student_terms, student_action_scale)


def make_chain_teacher(members: Sequence[Expert], student_terms: Sequence, student_action_scale):
    """The keyframe getup's latched chain as the teacher (switched_teacher): roll, rise, stand by
    obs[STAGE_OBS_KEY], the stage KeyframeStageObservation carries (common/events.keyframe_stage)."""
    if len(members) != len(events.KEYFRAME_STAGES):
        raise ValueError(f"a chain teacher has {len(events.KEYFRAME_STAGES)} members "
                         f"({', '.join(events.KEYFRAME_STAGES)}), got {len(members)}")
    return switched_teacher(tuple(members), lambda obs: obs[STAGE_OBS_KEY].astype(int), student_terms,
                            student_action_scale)


def make_kneeling_teacher(members: Sequence[Expert], student_terms: Sequence, student_action_scale,
                          switch_height_m: float = WAIST_SWITCH_HEIGHT_M):
    """The stitched teacher with the keyframe chain as its getup (switched_teacher): roll, rise, stand by
    obs[STAGE_OBS_KEY] while obs[WAIST_OBS_KEY] < switch_height_m, else the joystick expert (members: roll, rise,
    stand, joystick)."""
    if len(members) != len(KNEELING):
        raise ValueError(f"a kneeling teacher has {len(KNEELING)} members ({', '.join(KNEELING)}), got {len(members)}")
    joystick = len(CHAIN)
    return switched_teacher(tuple(members), lambda obs: jnp.where(obs[WAIST_OBS_KEY] >= switch_height_m, joystick,
                                                                  obs[STAGE_OBS_KEY]).astype(int),
                            student_terms, student_action_scale)


# a teacher's roles: the stitched teacher, the keyframe getup's chain, the chain below the waist switch and the
# joystick expert above it (the kneeling teacher)
STITCHED, CHAIN = ("getup", "joystick"), tuple(events.KEYFRAME_STAGES)
KNEELING = (*CHAIN, "joystick")
KINDS = (STITCHED, CHAIN, KNEELING)


def teacher_kind(roles) -> tuple[str, ...]:
    """STITCHED, CHAIN or KNEELING, from a teacher's roles (the keys of {role: policy} with a policy); a ValueError
    names any other set."""
    for kind in KINDS:
        if set(roles) == set(kind):
            return kind
    raise ValueError(f"a teacher is {' + '.join(STITCHED)} (the stitched teacher), {' + '.join(CHAIN)} (the "
                     f"keyframe getup's chain) or {' + '.join(KNEELING)} (the chain below the waist switch, the "
                     f"joystick expert above), got {sorted(roles)}")


def load_teacher(roles: dict, student_terms: Sequence, student_action_scale):
    """The teacher of {role: expert path} (teacher_kind's roles): make_teacher, make_chain_teacher or
    make_kneeling_teacher."""
    kind = teacher_kind(roles)
    experts = [load_expert(roles[role], role) for role in kind]
    if kind == STITCHED:
        return make_teacher(*experts, student_terms, student_action_scale)
    if kind == KNEELING:
        return make_kneeling_teacher(experts, student_terms, student_action_scale)
    return make_chain_teacher(experts, student_terms, student_action_scale)


def teacher_observation(roles: dict, handover_up_error: float = events.KNEEL_GATE_UP_ERROR):
    """The wrapper (wrapped env, base env) → env that puts what the teacher of these roles switches on into the
    observation; the chain's rise hands over to the stand at handover_up_error (keyframe_stage)."""
    kind = teacher_kind(roles)
    if kind == STITCHED:
        return WaistObservation
    if kind == KNEELING:
        return lambda wrapped, base_env: KeyframeStageObservation(WaistObservation(wrapped, base_env), base_env,
                                                                  handover_up_error)
    return functools.partial(KeyframeStageObservation, handover_up_error=handover_up_error)


def check_teacher(getup_path, joystick_path, num_envs: int = 16, seed: int = 0, steps: int = 50,
                  task: str = "getup") -> str:
    """Roll the stitched teacher out in the `task` env for `steps` control steps; a one-line summary."""
    checkpoints.jax_setup()
    getup, joystick = load_expert(getup_path, "getup"), load_expert(joystick_path, "joystick")
    overrides = {"fallen.bank_starts": CHECK_FALLEN_STARTS} if "fallen" in envs.default_config(task) else None
    env = envs.make(task, config_overrides=overrides)
    student_terms = obsdef.TERMS_UNION
    to_student = TermAdapter(env.obs_terms, student_terms)
    teacher = make_teacher(getup, joystick, student_terms, env.manifest_fields()["action_scale"])

    def act(state):
        obs = {STUDENT_OBS_KEY: to_student(state.obs[STUDENT_OBS_KEY]),
               WAIST_OBS_KEY: state.info["waist_height"][..., None]}
        return teacher(obs)[0], state.info["waist_height"] < WAIST_SWITCH_HEIGHT_M

    reset, step, act = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step)), jax.jit(jax.vmap(act))
    state = reset(jax.random.split(jax.random.PRNGKey(seed), num_envs))
    getup_share = []
    for _ in range(steps):
        action, used_getup = act(state)
        getup_share.append(float(jnp.mean(used_getup)))
        state = step(state, action)
    return (f"teacher OK: {num_envs} envs × {steps} steps in {task!r}; getup expert active "
            f"{100 * np.mean(getup_share):.0f}% of env-steps; final mean waist height "
            f"{float(jnp.mean(state.info['waist_height'])):.3f} m")

"""The stitched teacher of the distillation, from two experts (training/envs/experts.py).

Stitched teacher (ARCHITECTURE.md, Training): the getup expert while the waist is below
WAIST_SWITCH_HEIGHT_M, else the joystick expert. Waist height is privileged (state.info["waist_height"]);
brax bc's teacher sees only observations, so distillation adds it to the observation dict under
WAIST_OBS_KEY (training/distill.py); the student's network reads only "state".
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from common import observation as obsdef
from messages.contract import WAIST_SWITCH_HEIGHT_M
from training.envs.experts import STUDENT_OBS_KEY, WAIST_OBS_KEY, Expert, TermAdapter, load_expert, per_joint

CHECK_FALLEN_STARTS = 16  # host-precomputed fallen starts for the `teacher` check rollout (seconds each)


class WaistObservation:
    """Wraps a brax-training-wrapped (batched) env: adds obs[WAIST_OBS_KEY] = waist height (B, 1) [m],
    read from the physics data (so it is right after an auto-reset, when info is still the old one)."""

    def __init__(self, wrapped, base_env):
        import jax
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


def make_teacher(getup: Expert, joystick: Expert, student_terms: Sequence, student_action_scale,
                 student_tanh_squash: bool, switch_height_m: float = WAIST_SWITCH_HEIGHT_M):
    """brax-bc teacher: obs dict {"state": student-layout obs, "waist_height": (..., 1)} →
    (action, {"loc": label}) in the STUDENT's action map; the getup expert where waist height <
    switch_height_m. The experts' maps differ (joystick ±0.5 rad around home, getup up to 2 rad): each
    expert's action is turned into the same joint targets in the student's map, a_s = a_e · s_e / s_s
    (the student's scale is at least each expert's, so |a_s| ≤ 1).

    The observation's last action is mapped back the same way: an expert that reads `last_action` gets
    clip(a_s · s_s / s_e, −1, 1), the previous joint targets in ITS map, so while it drives it reads its own
    previous action, as when it was trained and in the runtime (read in the student's map, the joystick
    expert would see a quarter of its own action). The clip
    matters only on the first tick after the getup expert or the student acted with targets outside the expert's range.

    The label is what the student must output to execute a_s. brax bc's loss is
    ‖tanh(loc_student) − tanh(label)‖² whatever the student's output rule, so it is minimised at
    loc_student = label. A tanh-squashed student acts with tanh(loc): label = atanh(a_s). A student without
    squash (the seed's Table 5.2) acts with loc itself: label = a_s. (With atanh(a_s) it would execute
    atanh(a_s), e.g. 1.47 for a teacher's 0.9, overshooting every large getup target.)"""
    import jax.numpy as jnp
    to_getup = TermAdapter(student_terms, getup.obs_terms)
    to_joystick = TermAdapter(student_terms, joystick.obs_terms)
    s_student = per_joint(student_action_scale)
    ratios = {e.name: e.action_scale / s_student for e in (getup, joystick)}
    for e in (getup, joystick):
        if np.any(ratios[e.name] > 1.0 + 1e-6):
            raise ValueError(f"{e.name} expert's action scale exceeds the student's on some joint: the student "
                             "could not reach its targets (give the student env the larger scale)")
    last_action_at = {e.name: obsdef.term_slice(e.obs_terms, "last_action") for e in (getup, joystick)}

    def expert_obs(expert, adapter, state):
        """The student-layout observation in the expert's layout, with its last action in the expert's map."""
        obs = adapter(state)
        where = last_action_at[expert.name]
        if where is None:
            return obs
        own = jnp.clip(obs[..., where] / jnp.asarray(ratios[expert.name]), -1.0, 1.0)
        return obs.at[..., where].set(own)

    def in_student_map(expert, loc):
        ratio = jnp.asarray(ratios[expert.name])
        action = jnp.tanh(loc) * ratio
        if not student_tanh_squash:
            return action, action
        # where the maps agree keep loc exactly (no atanh round trip at saturation)
        return action, jnp.where(ratio == 1.0, loc, jnp.arctanh(jnp.clip(action, -1 + 1e-6, 1 - 1e-6)))

    def teacher(obs, key=None):
        del key  # deterministic experts
        state = obs[STUDENT_OBS_KEY]
        use_getup = obs[WAIST_OBS_KEY] < switch_height_m
        a_g, label_g = in_student_map(getup, getup.loc(expert_obs(getup, to_getup, state)))
        a_j, label_j = in_student_map(joystick, joystick.loc(expert_obs(joystick, to_joystick, state)))
        return jnp.where(use_getup, a_g, a_j), {"loc": jnp.where(use_getup, label_g, label_j)}

    return teacher


def check_teacher(getup_path, joystick_path, num_envs: int = 16, seed: int = 0, steps: int = 50,
                  task: str = "getup") -> str:
    """Roll the stitched teacher out in the `task` env for `steps` control steps; a one-line summary."""
    import jax
    import jax.numpy as jnp
    from training import checkpoints, envs
    checkpoints.jax_setup()
    getup, joystick = load_expert(getup_path, "getup"), load_expert(joystick_path, "joystick")
    overrides = {"fallen.bank_starts": CHECK_FALLEN_STARTS} if "fallen" in envs.default_config(task) else None
    env = envs.make(task, config_overrides=overrides)
    student_terms = obsdef.TERMS_UNION
    to_student = TermAdapter(env.obs_terms, student_terms)
    teacher = make_teacher(getup, joystick, student_terms, env.manifest_fields()["action_scale"],
                           student_tanh_squash=False)  # the check executes the action only

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

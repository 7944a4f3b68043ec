"""The measurement behind this run's PROGRESS.md, "The label fix": in states of the keyframe teacher's own
rollout (unified env, 64 envs × 120 ticks), does a student execute the teacher's action a, or atanh(a)?

    PYTHONPATH=$PWD:$PWD/build/gen/python .venv/bin/python training/runs/student_exec_labels/label_check.py STUDENT

STUDENT: a student artifact (.safetensors) or a distill checkpoint directory. ~2 min on 2 cores.
"""
import sys

import jax
import jax.numpy as jnp
import numpy as np

from training import checkpoints, envs
from training import observation as obsdef
from training.teacher import (STUDENT_OBS_KEY, WAIST_OBS_KEY, WAIST_SWITCH_HEIGHT_M, load_expert,
                              make_teacher)

ENVS, TICKS, SEED = 64, 120, 3
TEACHER = ("policies/getup_keyframe.safetensors", "policies/joystick.safetensors")


def student_layers(path: str):
    """(layers, obs mean, obs std, activation) of a linear-output student, artifact or checkpoint."""
    if path.endswith(".safetensors"):
        from training.artifact import read_artifact
        layers, mean, std, manifest = read_artifact(path)
        return layers, mean, std, manifest["activation"]
    from training.distill import loc_half
    from training.export import brax_policy_layers
    from training.train import ACTIVATION
    params = checkpoints.load_checkpoint(path)
    return (brax_policy_layers(loc_half(params[1])), params[0].mean[STUDENT_OBS_KEY],
            params[0].std[STUDENT_OBS_KEY], ACTIVATION)


def main(path: str) -> None:
    checkpoints.jax_setup()
    env = envs.make("unified", config_overrides={"fallen_bank_size": ENVS})
    teacher = make_teacher(load_expert(TEACHER[0], "getup"), load_expert(TEACHER[1], "joystick"), obsdef.TERMS_UNION,
                           env.manifest_fields()["action_scale"], student_tanh_squash=False)
    layers, mean, std, activation = student_layers(path)

    def act(state):
        obs = state.obs[STUDENT_OBS_KEY]
        a_teacher, _ = teacher({STUDENT_OBS_KEY: obs, WAIST_OBS_KEY: state.info["waist_height"][..., None]})
        a_student = obsdef.mlp_forward(layers, obsdef.normalize(obs, jnp.asarray(mean), jnp.asarray(std)),
                                       activation, "linear", xp=jnp)
        return a_teacher, a_student, state.info["waist_height"] < WAIST_SWITCH_HEIGHT_M

    reset, step, act = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step)), jax.jit(jax.vmap(act))
    state = reset(jax.random.split(jax.random.PRNGKey(SEED), ENVS))
    rows = []
    for _ in range(TICKS):
        a_teacher, a_student, getup = act(state)
        rows.append((np.asarray(a_teacher), np.asarray(a_student), np.asarray(getup)))
        state = step(state, a_teacher)             # the teacher drives: its own states
    teacher_a, student_a, getup = (np.concatenate(x) for x in zip(*rows))
    t, s = teacher_a[getup], student_a[getup]
    atanh_t = np.arctanh(np.clip(t, -0.999, 0.999))
    big = np.abs(t) > 0.8
    print(f"getup expert active in {getup.mean():.0%} of env-steps; |a| > 0.8 in {big.mean():.1%} of its actions")
    print(f"student's mean abs error to a: {np.abs(s - t).mean():.3f}; to atanh(a): {np.abs(s - atanh_t).mean():.3f}")
    print(f"where |a| > 0.8: teacher mean |a| {np.abs(t[big]).mean():.3f}, student {np.abs(s[big]).mean():.3f}, "
          f"atanh(a) {np.abs(atanh_t[big]).mean():.3f} (× 2 rad per unit)")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])

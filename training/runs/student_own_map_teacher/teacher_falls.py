"""The measurement behind this run's PROGRESS.md: how often does the stitched teacher fall while walking?
Unified env (full-body collision, the joystick env's commands and pushes), standing starts only, the teacher
drives, CPU backend. A fall = the waist going below the switch height (0.5 m) from above.

    PYTHONPATH=$PWD:$PWD/build/gen/python .venv/bin/python training/runs/student_own_map_teacher/teacher_falls.py [--student-map]

--student-map: the joystick expert reads the env's last action as it is, in the student's map (a quarter of
its own), which is what make_teacher fed it before this run. ~1 min on 2 cores for 128 envs × 1000 ticks.
"""
import argparse

import jax
import jax.numpy as jnp
import numpy as np

from training import checkpoints, envs
from training import observation as obsdef
from training.teacher import STUDENT_OBS_KEY, WAIST_OBS_KEY, WAIST_SWITCH_HEIGHT_M, load_expert, make_teacher

TEACHER = ("training/runs/getup_keyframe_energy/getup_keyframe_energy.safetensors", "policies/joystick.safetensors")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--student-map", action="store_true", help="the old reading of the last action (see above)")
    ap.add_argument("--envs", type=int, default=128)
    ap.add_argument("--ticks", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=7)
    args = ap.parse_args()
    checkpoints.jax_setup()
    cfg = envs.default_config("unified")
    cfg.backend, cfg.start_probs = "cpu", [0.0, 0.0, 1.0]
    env = envs.make("unified", config=cfg)
    getup, joystick = load_expert(TEACHER[0], "getup"), load_expert(TEACHER[1], "joystick")
    student_scale = env.manifest_fields()["action_scale"]
    teacher = make_teacher(getup, joystick, obsdef.TERMS_UNION, student_scale, student_tanh_squash=False)
    at = obsdef.term_slice(obsdef.TERMS_UNION, "last_action")
    old_view = np.asarray(joystick.action_scale / np.broadcast_to(student_scale, joystick.action_scale.shape))

    def act(state):
        obs = state.obs[STUDENT_OBS_KEY]
        if args.student_map:   # make_teacher multiplies by s_s / s_e: undo it, so the expert reads obs as is
            obs = obs.at[..., at].multiply(jnp.asarray(old_view))
        return teacher({STUDENT_OBS_KEY: obs, WAIST_OBS_KEY: state.info["waist_height"][..., None]})[0]

    reset, step, act = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step)), jax.jit(jax.vmap(act))
    state = reset(jax.random.split(jax.random.PRNGKey(args.seed), args.envs))
    up, falls, tracking = np.ones(args.envs, bool), np.zeros(args.envs), []
    for _ in range(args.ticks):
        state = step(state, act(state))
        standing = np.asarray(state.info["waist_height"]) >= WAIST_SWITCH_HEIGHT_M
        falls += up & ~standing
        up = standing
        tracking.append(float(np.mean(np.asarray(state.metrics["reward/tracking_lin_vel"]))))
    print(f"{'student-map' if args.student_map else 'own-map'} last action: {args.envs} standing starts × "
          f"{args.ticks} ticks: {int(falls.sum())} falls, {int((falls > 0).sum())} envs fell at least once, "
          f"tracking_lin_vel reward {np.mean(tracking):.3f} per tick, standing at the end {up.mean():.1%}")


if __name__ == "__main__":
    main()

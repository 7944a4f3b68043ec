"""The measurement behind this run's PROGRESS.md: how often does the stitched teacher fall while walking?
Unified env (full-body collision, the joystick env's commands and pushes), standing (default) or fallen starts
only, the teacher drives, CPU backend. A fall = the trunk dropping below sim_hil's fallen
height (0.35 m) after standing (trunk ≥ 0.6 m, up_z ≥ 0.9: sim_hil/eval/events.py, as the loop counts attempts);
from a fallen start, every fall is a fall back after a getup.

    PYTHONPATH=$PWD:$PWD/build/gen/python .venv/bin/python training/runs/student_own_map_teacher/teacher_falls.py [--student-map]
        [--start standing|fallen] [--getup G] [--joystick J]

--student-map: the joystick expert reads the env's last action as it is, in the student's map (a quarter of
its own), which is what make_teacher fed it before this run. ~1 min on 2 cores for 128 envs × 1000 ticks.
"""
import argparse

import jax
import jax.numpy as jnp
import numpy as np

from sim_hil.config import FALLEN_TRUNK_HEIGHT_M
from sim_hil.eval.events import STANDING_TRUNK_HEIGHT_M, UPRIGHT_UP_Z
from training import checkpoints, envs
from training import observation as obsdef
from training.teacher import STUDENT_OBS_KEY, WAIST_OBS_KEY, WAIST_SWITCH_HEIGHT_M, load_expert, make_teacher

QUICK_FALL_TICKS = 150     # a fall this soon after coming to standing [ticks of 0.02 s]: a failed hand-over
TEACHER = ("training/runs/getup_keyframe_energy/getup_keyframe_energy.safetensors", "policies/joystick.safetensors")


def standing(info) -> np.ndarray:
    return (np.asarray(info["trunk_height"]) >= STANDING_TRUNK_HEIGHT_M) & (np.asarray(info["up_z"]) >= UPRIGHT_UP_Z)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--student-map", action="store_true", help="the old reading of the last action (see above)")
    ap.add_argument("--envs", type=int, default=128)
    ap.add_argument("--ticks", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--start", choices=("standing", "fallen"), default="standing")
    ap.add_argument("--getup", default=TEACHER[0], help="getup expert (artifact or checkpoint)")
    ap.add_argument("--joystick", default=TEACHER[1], help="joystick expert (artifact or checkpoint)")
    args = ap.parse_args()
    checkpoints.jax_setup()
    cfg = envs.default_config("unified")
    cfg.backend = "cpu"
    cfg.start_probs = [0.0, 0.0, 1.0] if args.start == "standing" else [1.0, 0.0, 0.0]
    env = envs.make("unified", config=cfg)
    getup, joystick = load_expert(args.getup, "getup"), load_expert(args.joystick, "joystick")
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
    up = standing(state.info)
    falls, quick_falls, tracking = np.zeros(args.envs), np.zeros(args.envs), []
    stood_at = np.full(args.envs, -10 ** 6)          # tick each env last came to standing
    for tick in range(args.ticks):
        state = step(state, act(state))
        now_up, down = standing(state.info), np.asarray(state.info["trunk_height"]) < FALLEN_TRUNK_HEIGHT_M
        fell = up & down
        falls += fell
        quick_falls += fell & (tick - stood_at <= QUICK_FALL_TICKS)
        stood_at = np.where(now_up & ~up, tick, stood_at)
        up = (up | now_up) & ~down
        tracking.append(float(np.mean(np.asarray(state.metrics["reward/tracking_lin_vel"]))))
    print(f"{'student-map' if args.student_map else 'own-map'} last action: {args.envs} {args.start} starts × "
          f"{args.ticks} ticks: {int(falls.sum())} falls ({int(quick_falls.sum())} within {QUICK_FALL_TICKS} ticks of "
          f"coming to standing), {int((falls > 0).sum())} envs fell at least once, "
          f"tracking_lin_vel reward {np.mean(tracking):.3f} per tick, standing at the end {np.mean(standing(state.info)):.1%}")


if __name__ == "__main__":
    main()

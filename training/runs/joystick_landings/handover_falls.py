"""The measurement behind this run's PROGRESS.md: does a joystick expert hold the robot the getup expert hands
it in the loop's push test? The hand-over states are handover.handover_bank's: the getup expert rises from
the push test's landings (handover.push_test_bank of the parent joystick expert, the screens' seeds 510000 …)
and the state of the first tick with the waist at or above the teacher's 0.5 m switch is kept. Each joystick
expert then drives alone from those states at zero command (the joystick env, full-body collision, no pushes
or noise, CPU physics) for HOLD_TICKS; a fall = the waist below FALLEN_WAIST_M. The hand-over states of
those that fell and of those held are compared (trunk speed, tilt, body rates).

    PYTHONPATH=$PWD:$PWD/build/gen/python .venv/bin/python training/runs/joystick_landings/handover_falls.py J [J …]
        [--getup G] [--landing-joystick JP] [--starts 256]

~2 min on 2 cores, most of it the bank.
"""
import argparse

import jax
import jax.numpy as jnp
import numpy as np

from training import envs
from training import observation as obsdef
from training.envs import handover
from training.teacher import STUDENT_OBS_KEY, load_expert

HOLD_TICKS = 150          # [ticks of 0.02 s] = 3 s after the hand-over
FALLEN_WAIST_M = 0.3      # [m] the waist this low = the robot is down again, not a dip the getup expert rescues
PUSH_SEED = 510_000       # the push screens' bank seed (training's push_starts bank is 500 000 …)
FALLEN_SEED = 1000        # fallen-bank seed of the getup env the bank is rolled in (its starts are all landings)


def tilt_deg(quat: np.ndarray) -> np.ndarray:
    """The trunk's tilt from vertical [deg] of (w, x, y, z) root quaternions."""
    return np.degrees(np.arccos(np.clip(1.0 - 2.0 * (quat[:, 1] ** 2 + quat[:, 2] ** 2), -1.0, 1.0)))


def held_after_handover(env, bank: handover.HandoverBank, joystick_policy: str) -> np.ndarray:
    """Per hand-over state: did `joystick_policy` keep the waist above FALLEN_WAIST_M for HOLD_TICKS?"""
    joystick = load_expert(joystick_policy, "joystick")
    act = jax.jit(jax.vmap(lambda obs: jnp.tanh(joystick.loc(obs))))
    n = bank.qpos.shape[0]
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), n))
    data = jax.vmap(env.make_data)(jnp.asarray(bank.qpos), jnp.asarray(bank.qvel))
    last_act = jax.vmap(lambda t: obsdef.targets_to_action(env._default_pose, env._action_scale, t, jnp))(
        jnp.asarray(bank.joint_targets))
    info = {**state.info, "last_act": last_act, "command": jnp.zeros((n, 3)),
            "runtime_target": jax.vmap(env.start_target)(data.qpos), **jax.vmap(env.body_readings)(data)}
    obs = jax.vmap(env._observe)(data, info, jax.vmap(env.foot_contacts)(data),
                                 jax.random.split(jax.random.PRNGKey(1), n))
    state = state.replace(data=data, info=info, obs=obs)
    step = jax.jit(jax.vmap(env.step))
    lowest = np.full(n, np.inf)
    for _ in range(HOLD_TICKS):
        state = step(state, act(state.obs[STUDENT_OBS_KEY]))
        lowest = np.minimum(lowest, np.asarray(state.info["waist_height"]))
    return lowest >= FALLEN_WAIST_M


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("joystick", nargs="+", help="joystick experts (artifacts or checkpoints) to hold the robot")
    ap.add_argument("--getup", default="training/runs/getup_kd_bank/getup_kd_bank.safetensors")
    ap.add_argument("--landing-joystick", default="training/runs/joystick_handover_gpu/joystick.safetensors",
                    help="the joystick expert the push test shoves over (whose landings the getup expert rises from)")
    ap.add_argument("--starts", type=int, default=256, help="rises drawn (identical hand-overs kept once)")
    args = ap.parse_args()
    bank = handover.handover_bank(args.getup, args.starts, FALLEN_SEED, {
        "push_starts.prob": 1.0, "push_starts.joystick_policy": args.landing_joystick,
        "push_starts.seed": PUSH_SEED, "push_starts.bank_starts": args.starts})
    env = envs.make("joystick", config_overrides={"backend": "cpu", "collision": "full_body", "push.enable": False,
                                                  "noise.level": 0.0})
    features = {"trunk vz [m/s]": bank.qvel[:, 2], "trunk |v_xy| [m/s]": np.hypot(bank.qvel[:, 0], bank.qvel[:, 1]),
                "|ω| [rad/s]": np.linalg.norm(bank.qvel[:, 3:6], axis=1), "tilt [deg]": tilt_deg(bank.qpos[:, 3:7]),
                "|q̇| joints [rad/s]": np.linalg.norm(bank.qvel[:, 6:], axis=1)}
    print(f"{bank.qpos.shape[0]} distinct hand-overs of {args.getup} from push-test landings of "
          f"{args.landing_joystick}")
    for path in args.joystick:
        held = held_after_handover(env, bank, path)
        print(f"\n{path}: fell (waist < {FALLEN_WAIST_M} m within {HOLD_TICKS} ticks) after "
              f"{(~held).sum()} of {held.size} hand-overs\n"
              "| at the hand-over, 10 / 50 / 90 % | held | fell |\n|---|---|---|")
        for name, value in features.items():
            row = [np.percentile(value[mask], [10, 50, 90]).round(2) if mask.any() else "—" for mask in (held, ~held)]
            print(f"| {name} | {' / '.join(map(str, row[0]))} | {' / '.join(map(str, row[1]))} |")


if __name__ == "__main__":
    main()

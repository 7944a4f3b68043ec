"""The measurement behind this run's PROGRESS.md "failed rises before the switch": in the push screen, what do
the getup attempts that fail BEFORE the waist reaches the teacher's 0.5 m switch look like?

The composite GETUP,JOYSTICK (the teacher as the runtime stitches it) rises from the push test's landings
(handover.push_test_bank of the landing joystick expert, the screens' seeds 510000 …; CPU physics, as
`evaluate --starts push`), the pose kept at every control tick. Each episode's attempts come from
sim_hil/eval/events.py (GetupEvents.attempt_log, the definitions the loop counts with). Every attempt is
described: when it started (s after the landing), the Trunk's up_z then, which way the shove threw it (the
landing's trunk velocity along its heading), how high trunk and waist got, and whether it passed the seed's
kneel gate (§4.8: trunk ≥ 0.395 m within 0.573° of vertical, where the getup reward turns to standing).
Failed attempts before the switch are compared with the first attempts that stood; --render K writes frame
strips (start, ¼, ½, ¾, end) of K failed ones.

    PYTHONPATH=$PWD:$PWD/build/gen/python MUJOCO_GL=osmesa PYOPENGL_PLATFORM=osmesa \
        .venv/bin/python training/runs/getup_pace5/prerise_falls.py [--policy G,J] [--render 6] [--out DIR]

~1 min on 2 cores.
"""
import argparse
import csv
import math
from collections import Counter
from pathlib import Path

import numpy as np

from sim_hil.eval.events import getup_events, heading_from_quat, kneel_gate_mask
from training import checkpoints, envs
from training.artifact_policy import load_policy
from training.envs import handover
from training.evaluate_cpu import cpu_rollout
from messages.contract import WAIST_SWITCH_HEIGHT_M

JOYSTICK = "training/runs/joystick_handover_gpu/joystick.safetensors"
GETUP = "training/runs/getup_pace5/getup_pace5_3522560.safetensors"
PUSH_SEED, PUSH_STARTS = 510_000, 192      # the push screens' bank
SECONDS = 10.0
STRIP_PX = 240       # [px] height and width of one rendered frame


def shove_direction(qpos: np.ndarray, qvel: np.ndarray) -> str:
    """forward / backward: the landing's trunk velocity along the Trunk's heading."""
    yaw = heading_from_quat(qpos[3:7])
    return "forward" if math.cos(yaw) * qvel[0] + math.sin(yaw) * qvel[1] >= 0.0 else "backward"


def describe(t, run, i, bank_qpos, bank_qvel) -> list[dict]:
    """Every attempt of episode i with its start-state features."""
    trunk, up_z, waist = (run["readings"][i, :, k] for k in range(3))
    ev = getup_events(t, trunk, up_z, waist_height=waist, switch_height_m=WAIST_SWITCH_HEIGHT_M)
    gate = kneel_gate_mask(trunk, up_z)
    rows = []
    for number, a in enumerate(ev.attempt_log, 1):
        k0 = int(np.searchsorted(t, a.start_s - 1e-9))
        k1 = len(t) - 1 if np.isnan(a.end_s) else int(np.searchsorted(t, a.end_s - 1e-9))
        rows.append({"episode": i, "number": number, "outcome": a.outcome, "switched": a.switched,
                     "start_s": a.start_s, "end_s": a.end_s, "start_tick": k0, "end_tick": k1,
                     "peak_trunk_m": a.peak_trunk_m, "peak_waist_m": float(waist[k0:k1 + 1].max()),
                     "kneel_gate": bool(gate[k0:k1 + 1].any()), "up_z": float(up_z[k0]),
                     "shove": shove_direction(bank_qpos[i], bank_qvel[i])})
    return rows


def summary(name: str, rows: list[dict]) -> str:
    if not rows:
        return f"| {name} | 0 | — | — | — | — | — | — |"
    pct = lambda key: " / ".join(f"{v:.2f}" for v in np.percentile([r[key] for r in rows], [10, 50, 90]))
    share = lambda key: ", ".join(f"{k} {v}" for k, v in sorted(Counter(r[key] for r in rows).items()))
    return (f"| {name} | {len(rows)} | {pct('start_s')} | {pct('up_z')} | {share('shove')} | "
            f"{pct('peak_trunk_m')} | {pct('peak_waist_m')} | {sum(r['kneel_gate'] for r in rows)} |")


def render_strips(env, run, failed: list[dict], count: int, out: Path) -> None:
    import mediapy
    from sim_hil.recorder import render_frames, tracking_camera
    for r in failed[:count]:
        ticks = np.linspace(r["start_tick"], r["end_tick"], 5).round().astype(int)
        frames = render_frames(env.mj_model, list(run["qpos"][r["episode"], ticks].astype(np.float64)),
                               tracking_camera(env.mj_model), STRIP_PX, STRIP_PX)
        mediapy.write_image(str(out / f"episode{r['episode']:03d}_attempt{r['number']}.png"), np.hstack(frames))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--policy", default=f"{GETUP},{JOYSTICK}", help="GETUP,JOYSTICK composite")
    ap.add_argument("--landing-joystick", default=JOYSTICK, help="the expert the push test shoves over")
    ap.add_argument("--render", type=int, default=0, help="frame strips of this many failed pre-switch rises")
    ap.add_argument("--out", type=Path, default=Path("training/runs/getup_pace5/prerise_falls"))
    args = ap.parse_args()
    checkpoints.jax_setup()
    args.out.mkdir(parents=True, exist_ok=True)
    qpos, qvel = handover.push_test_bank(args.landing_joystick, PUSH_STARTS, PUSH_SEED)
    env = envs.make("getup", config_overrides={"backend": "cpu"})
    policy = load_policy(args.policy)
    policy.check_env(env)
    ticks = int(round(SECONDS / float(policy.manifest["control_dt"])))
    run = cpu_rollout(env, policy, np.asarray(qpos), np.asarray(qvel), ticks, keep_qpos=True)
    t = np.arange(ticks + 1) * float(policy.manifest["control_dt"])
    attempts = [row for i in range(len(qpos)) for row in describe(t, run, i, qpos, qvel)]
    failed_before = [r for r in attempts if r["outcome"] == "failed" and not r["switched"]]
    failed_after = [r for r in attempts if r["outcome"] == "failed" and r["switched"]]
    first_stood = [r for r in attempts if r["number"] == 1 and r["outcome"] == "stood"]
    first_failed_before = [r for r in failed_before if r["number"] == 1]
    per_landing = np.bincount([r["episode"] for r in attempts], minlength=len(qpos))
    lines = [f"{args.policy}: {len(qpos)} push-test landings, {len(attempts)} attempts "
             f"({per_landing.mean():.2f} per landing, most {per_landing.max()})", "",
             "| attempts | n | start [s after landing] 10/50/90 % | up_z at start | shove | "
             "peak trunk [m] | peak waist [m] | through the kneel gate |", "|---|---|---|---|---|---|---|---|",
             summary("failed before the switch", failed_before),
             summary("… of them first attempts", first_failed_before),
             summary("failed after the switch", failed_after),
             summary("first attempts that stood", first_stood)]
    landings = Counter(shove_direction(qpos[i], qvel[i]) for i in range(len(qpos)))
    lines += ["", "landings by shove: " + ", ".join(f"{k} {v}" for k, v in sorted(landings.items()))]
    text = "\n".join(lines)
    print(text)
    (args.out / "summary.md").write_text(text + "\n")
    with (args.out / "attempts.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(attempts[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(attempts)
    if args.render:
        render_strips(env, run, failed_before, args.render, args.out)


if __name__ == "__main__":
    main()

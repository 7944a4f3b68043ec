"""`python -m training.planner`: plan rises to the kneel from the loop's fallen starts and store them.

    python -m training.planner --seeds 0:100 --out DIR [--config samples=96 ...] [--max-minutes M]

Each seed's start is the getup env's fallen start of that seed after the runtime's PREPARE ramp; its plan
is seeded by the seed, so a folder is reproducible from its config. A seed whose demo_<seed>.npz is already in
DIR is kept (a stopped run goes on). DIR gets report.json after every demo and, at the end, frame strips of a
face-down and an on-the-back rise (strip_face_down.png, strip_on_back.png)."""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from training.overrides import apply_overrides
from training.planner import config as planner_config
from training.planner import demos
from training.planner.mppi import Planner


def parse_seeds(text: str) -> list[int]:
    """'A:B' (A … B − 1) or 'A,B,C'."""
    try:
        if ":" in text:
            a, b = (int(x) for x in text.split(":"))
            seeds = list(range(a, b))
        else:
            seeds = [int(x) for x in text.split(",")]
    except ValueError:
        raise ValueError(f"--seeds {text!r}: expected A:B or A,B,C (non-negative integers)") from None
    if not seeds or min(seeds) < 0:
        raise ValueError(f"--seeds {text!r}: expected at least one non-negative seed")
    return seeds


def build(overrides: list[str]):
    """(config, getup env on the CPU backend, planner): the env gives the training physics and the starts."""
    from training import envs
    cfg = planner_config.default_config()
    apply_overrides({"planner": cfg}, overrides)
    env = envs.make("getup", config_overrides={"backend": "cpu", "stage": "stage1", "fallen_bank_size": 1})
    fields = env.manifest_fields()
    planner = Planner(env.cpu_physics, cfg, np.asarray(fields["default_pose"]), np.asarray(fields["action_scale"]))
    return cfg, env, planner


def run(seeds: list[int], out: Path, overrides: list[str], max_minutes: float | None = None,
        log=print) -> dict:
    cfg, env, planner = build(overrides)
    out.mkdir(parents=True, exist_ok=True)
    old = out / demos.REPORT
    if old.exists() and json.loads(old.read_text())["config"] != cfg.to_dict():
        raise ValueError(f"{out}: its demonstrations were planned with another config; use a new folder")
    rows, kept = [], {}
    started = time.monotonic()
    for seed in seeds:
        qpos, qvel = (a[0].astype(np.float64) for a in env.fallen_starts(1, seed))
        side = demos.start_side(planner.model, qpos)
        path = out / f"demo_{seed}.npz"
        if path.exists():
            demo = demos.load(path)
        else:
            if max_minutes is not None and time.monotonic() - started > 60.0 * max_minutes:
                log(f"planner: --max-minutes {max_minutes:g} reached; {len(rows)} of {len(seeds)} seeds planned")
                break
            demo = planner.rise(qpos, qvel, planner.default_pose, seed)
            demos.save(demo, out)
        rows.append(demos.row(demo, side))
        shown = kept.get(side)          # each side's strip shows its first rise that met the gate, else its first
        if shown is None or (shown.gate_time_s is None and demo.gate_time_s is not None):
            kept[side] = demo
        demos.write_report(out, cfg, rows)
        r = rows[-1]
        log(f"seed {seed:4d} {side:9s} gate {r['gate_time_s'] if r['gate_time_s'] is not None else '–':>5} s  "
            f"held {r['held_share']:.2f}  end trunk {r['final_trunk_m']:.3f} m up_z {r['final_up_z']:.4f}  "
            f"{r['energy_J']:.0f} J  {r['cpu_s']:.0f} CPU s")
    for side in ("face_down", "on_back"):
        if side in kept:
            demos.frame_strip(planner.model, kept[side], out / f"strip_{side}.png")
    return demos.write_report(out, cfg, rows) if rows else {}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m training.planner", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seeds", required=True, help="fallen-start seeds: A:B or A,B,C")
    p.add_argument("--out", required=True, type=Path, help="the demonstrations' folder")
    p.add_argument("--config", action="append", default=[], metavar="KEY=VALUE",
                   help="planner setting (training/planner/config.py), repeatable")
    p.add_argument("--max-minutes", type=float, default=None, help="start no new seed after this long")
    args = p.parse_args(argv)
    try:
        seeds = parse_seeds(args.seeds)
        report = run(seeds, args.out, args.config, args.max_minutes)
    except ValueError as e:
        print(f"planner: {e}", file=sys.stderr)
        return 2
    print(json.dumps(report.get("summary", {}), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

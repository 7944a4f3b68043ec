"""Demonstrations on disk, the planner's report and its figures.

A demonstration set is one folder: `demo_<seed>.npz` (mppi.Demonstration's arrays, float32) and `report.json`
(the config, then per demo its seed, start side, gate time, energy and CPU seconds). `summarise` splits the
demos by how the robot lay at the start: face down, on the back, on a side (the trunk's forward axis)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import PIL.Image

from common.render import render_frames, tracking_camera  # first: it picks the offscreen GL before mujoco loads

# isort: split
from common.events import LYING_SIDES, lying_side
from common.model import trunk_forward_z
from training.envs.starts import demos as demo_starts
from training.planner.mppi import Demonstration

ARRAYS = ("qpos", "qvel", "obs", "targets", "trunk_height", "up_z", "gate", "kneeling", "waypoint")
REPORT = "report.json"
STRIP_CAMERA_DISTANCE_M = 1.6   # the frame strips' tracking camera, closer than the videos' (a lying robot is small)


def start_side(qpos: np.ndarray) -> str:
    """How a fallen start lies (common/events.py's rule on the trunk's forward axis)."""
    return lying_side(float(trunk_forward_z(qpos)))


def save(demo: Demonstration, folder: Path) -> Path:
    path = Path(folder) / f"demo_{demo.seed}.npz"
    kinds = {"gate": bool, "kneeling": bool, "waypoint": np.int8}
    arrays = {k: np.asarray(getattr(demo, k), kinds.get(k, np.float32)) for k in ARRAYS}
    np.savez_compressed(path, **arrays, energy_J=demo.energy_J, cpu_s=demo.cpu_s, ctrl_dt=demo.ctrl_dt)
    return path


def load(path: Path) -> Demonstration:
    path = Path(path)
    try:
        z = np.load(path)
        seed = int(path.stem.split("_", 1)[1])
        return Demonstration(seed=seed, **{k: z[k] for k in ARRAYS}, energy_J=float(z["energy_J"]),
                             cpu_s=float(z["cpu_s"]), ctrl_dt=float(z["ctrl_dt"]))
    except (OSError, KeyError, ValueError, IndexError) as e:
        raise ValueError(f"{path}: not a planner demonstration ({e})") from e


def min_tilt_deg(demo: Demonstration) -> float | None:
    """The trunk's smallest tilt from vertical [deg] while at the gate's height in the kneeling posture: how close
    a rise came to §4.8's 0.57° (None: never there)."""
    there = demo_starts.at_kneel(demo.trunk_height, demo.kneeling)
    return float(np.degrees(np.arccos(np.clip(demo.up_z[there], -1.0, 1.0))).min()) if there.any() else None


def row(demo: Demonstration, side: str) -> dict:
    tilt = min_tilt_deg(demo)
    gate_s = demo.gate_time_s
    return {"min_tilt_deg": round(tilt, 2) if tilt is not None else None, "seed": demo.seed, "side": side,
            "gate_time_s": round(gate_s, 2) if gate_s is not None else None,
            "seconds": round(len(demo.targets) * demo.ctrl_dt, 2),
            "energy_J": round(demo.energy_J, 1), "cpu_s": round(demo.cpu_s, 1),
            "final_trunk_m": round(float(demo.trunk_height[-1]), 3), "final_up_z": round(float(demo.up_z[-1]), 4),
            "held_share": round(float(np.mean((demo.gate & demo.kneeling)[_first(demo):])), 3)
            if demo.gate_time_s is not None else 0.0}


def _first(demo: Demonstration) -> int:
    return int(np.flatnonzero(demo.gate & demo.kneeling)[0])


def write_report(folder: Path, cfg, rows: list[dict]) -> dict:
    report = {"config": cfg.to_dict(), "demos": sorted(rows, key=lambda r: r["seed"]), "summary": summarise(rows)}
    (Path(folder) / REPORT).write_text(json.dumps(report, indent=1))
    return report


def summarise(rows: list[dict], within_s: float = 6.0) -> dict:
    """Per start side and in all: demos, the share meeting the gate in the kneeling posture within
    within_s (and by the demo's end: the later ones are demonstrations too), the median gate time, CPU seconds
    per demo and energy [J]."""
    out = {}
    for side in (*LYING_SIDES, "all"):
        rs = [r for r in rows if side in ("all", r["side"])]
        if not rs:
            continue
        met = [r for r in rs if r["gate_time_s"] is not None and r["gate_time_s"] <= within_s]
        out[side] = {"demos": len(rs), "met_gate": len(met), "share": round(len(met) / len(rs), 3),
                     "met_gate_by_end": sum(r["gate_time_s"] is not None for r in rs),
                     "median_gate_time_s": float(np.median([r["gate_time_s"] for r in met])) if met else None,
                     "median_held_share": float(np.median([r["held_share"] for r in met])) if met else None,
                     "reached_kneeling_height": sum(r.get("min_tilt_deg") is not None for r in rs),
                     "best_tilt_deg": min((r["min_tilt_deg"] for r in rs if r.get("min_tilt_deg") is not None),
                                          default=None),
                     "median_cpu_s": float(np.median([r["cpu_s"] for r in rs])),
                     "median_energy_J": float(np.median([r["energy_J"] for r in rs]))}
    return out


def frame_strip(model, demo: Demonstration, out_png: Path, frames: int = 8, px: int = 240) -> Path:
    """`frames` states of the demonstration, evenly spaced in time, left to right, from the robot's side."""
    idx = np.linspace(0, len(demo.qpos) - 1, frames).round().astype(int)
    camera = tracking_camera(model)
    camera.distance = STRIP_CAMERA_DISTANCE_M
    pics = render_frames(model, [demo.qpos[i].astype(np.float64) for i in idx], camera, px, px)
    PIL.Image.fromarray(np.concatenate(pics, axis=1)).save(out_png, optimize=True)
    return Path(out_png)


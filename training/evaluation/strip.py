"""A frame strip of one getup, for a policy's card: the first held-back fallen start lying the asked way, rolled out
as the batch evaluation does (CPU backend), drawn from the robot's side at the getup's moments: frames evenly in
time up to the kneel (the band's condition met in the kneeling posture, common/events), the kneel itself, frames
on the way up, the first stand-up and the stand after it.
`python -m training strip --policy policies/getup_keyframe --lying on_back --out strip.png`."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import PIL.Image
import PIL.ImageDraw

from common.render import render_frames, tracking_camera  # first: it picks the offscreen GL before mujoco loads

# isort: split
from common import events
from common import model as t1model
from messages.contract import WAIST_SWITCH_HEIGHT_M
from training import envs
from training.core import checkpoints
from training.evaluation.artifact_policy import load_policy
from training.evaluation.cpu import cpu_rollout

CAMERA_DISTANCE_M = 2.2   # the tracking camera's distance for a strip (the whole body lying or standing)
SEARCH_SEEDS = 64         # fallen seeds looked through for one lying the asked way
AFTER_STAND_S = 2.0       # [s] the last frame: this long after the first stand-up
FRAME_PX = 240
LABEL_MARGIN_PX = 6


def first_seed_lying(env, side: str, first_seed: int) -> int:
    """The first fallen seed from first_seed whose start lies `side` (common/events.lying_side)."""
    if side not in events.LYING_SIDES:
        raise ValueError(f"lying {side!r}: one of {', '.join(events.LYING_SIDES)}")
    qpos, _ = env.fallen_starts(SEARCH_SEEDS, first_seed)
    sides = [events.lying_side(float(z)) for z in t1model.trunk_forward_z(np.asarray(qpos))]
    if side not in sides:
        raise ValueError(f"none of the fallen seeds {first_seed} … {first_seed + SEARCH_SEEDS - 1} lies {side}")
    return first_seed + sides.index(side)


def moments(t, readings, frames: int) -> tuple[list[int], list[str]]:
    """Ticks to draw and their labels: `frames` in all, the kneel (band, in the kneeling posture) and the first
    stand-up among them when the episode has them. readings (T + 1, 4): trunk, up_z, waist, kneeling posture."""
    h, u, kneeling = readings[:, 0], readings[:, 1], readings[:, 3] > 0.5
    ev = events.getup_events(t, h, u, waist_height=readings[:, 2], switch_height_m=WAIST_SWITCH_HEIGHT_M)
    last = len(t) - 1
    if math.isnan(ev.time_to_stand_s):
        ticks = np.linspace(0, last, frames).round().astype(int)
        return list(ticks), [f"{t[i]:.1f} s" for i in ticks]
    stand = int(np.searchsorted(t, t[0] + ev.time_to_stand_s - 1e-9))
    end = min(last, stand + int(round(AFTER_STAND_S / (t[1] - t[0]))))
    band = np.flatnonzero(events.kneel_gate(h[:stand], u[:stand], np, events.KNEEL_BAND_UP_ERROR) & kneeling[:stand])
    if band.size == 0:                     # it stood up without the kneel: evenly up to the stand
        ticks = [*np.linspace(0, stand, frames - 1).round().astype(int), end]
        return ticks, [f"{t[i]:.1f} s" for i in ticks[:-2]] + [f"{t[stand]:.1f} s stood", f"{t[end]:.1f} s"]
    kneel = int(band[0])
    before = max(1, (frames - 3) * 2 // 3)            # the roll and the rise get most of the frames
    rise = np.linspace(0, kneel, before + 1).round().astype(int)[:-1]
    up = np.linspace(kneel, stand, frames - before - 1).round().astype(int)[1:-1]
    ticks = [*rise, kneel, *up, stand, end]
    labels = ([f"{t[i]:.1f} s" for i in rise] + [f"{t[kneel]:.1f} s kneel"] + [f"{t[i]:.1f} s" for i in up]
              + [f"{t[stand]:.1f} s stood", f"{t[end]:.1f} s"])
    return ticks, labels


def getup_strip(policy_path: str, out_png, lying: str = "on_back", first_seed: int = 9500, seconds: float = 15.0,
                frames: int = 8, handover_up_error: float | None = None) -> tuple[Path, int, list[str]]:
    """Roll out `policy_path` (artifact, GETUP,UPRIGHT or a chain) from the first held-back fallen start lying
    `lying` and draw `frames` moments of it into out_png; returns (path, seed, frame labels)."""
    checkpoints.jax_setup()
    if frames < 4:
        raise ValueError(f"--frames {frames}: at least 4 (the start, the kneel, the stand-up and after it)")
    env = envs.make("getup", config_overrides={"backend": "cpu"})
    policy = load_policy(policy_path, handover_up_error)
    policy.check_env(env)
    seed = first_seed_lying(env, lying, first_seed)
    qpos, qvel = env.fallen_starts(1, seed)
    ticks_total = int(round(seconds / float(policy.manifest["control_dt"])))
    series = cpu_rollout(env, policy, np.asarray(qpos), np.asarray(qvel), ticks_total, keep_qpos=True)
    t = np.arange(ticks_total + 1) * float(policy.manifest["control_dt"])
    ticks, labels = moments(t, series["readings"][0], frames)
    camera = tracking_camera(env.mj_model)
    camera.distance = CAMERA_DISTANCE_M
    pics = render_frames(env.mj_model, [series["qpos"][0, i].astype(np.float64) for i in ticks], camera,
                         FRAME_PX, FRAME_PX)
    strip = PIL.Image.fromarray(np.concatenate(pics, axis=1))
    draw = PIL.ImageDraw.Draw(strip)
    for i, label in enumerate(labels):                   # each frame's time (and moment) at its top left
        draw.text((i * FRAME_PX + LABEL_MARGIN_PX, LABEL_MARGIN_PX), label, fill=(255, 255, 255))
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    strip.save(out_png, optimize=True)
    return out_png, seed, labels

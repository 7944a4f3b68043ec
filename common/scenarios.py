"""Evaluation scenarios composed onto the T1 model (shared by MJX batch eval and HIL).

Composition is done with MjSpec editing (mujoco 4.0): the base file common/models/t1.xml (robot +
floor) is parsed once per build, static world geoms are added, and the spec is compiled. This keeps one
robot file, needs no XML fragment files on disk, and lets the layouts be seeded.

The walking path is +x from the origin (where the robot spawns).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from common.model import robot_spec

SCENARIOS = ("flat", "walls", "puddles", "pushes", "tall_wall")

# low walls: 3 walls, 0.2 m tall, 0.1 m thick, 40 m long along y, centres 6 m apart from x = 2 m -----
WALL_COUNT = 3
WALL_HEIGHT_M = 0.2
WALL_THICKNESS_M = 0.1
WALL_LENGTH_M = 40.0
WALL_FIRST_X_M = 2.0   # x of the first wall's centre plane [m]
WALL_SPACING_M = 6.0

# tall wall: one wall the robot can lean on, its face just ahead of the standing spawn ---------------------
TALL_WALL_FACE_X_M = 0.35       # x of the face toward the robot [m]: a step and a half ahead of the trunk
TALL_WALL_HEIGHT_M = 1.5
TALL_WALL_THICKNESS_M = 0.2

# puddles: low-friction patches on the walking path ----------------------------------------------------
PUDDLE_FRICTION = 0.4           # sliding μ (floor: 0.6)
PUDDLE_SIDE_M = (0.6, 1.0)      # side lengths, uniform [m]
PUDDLE_PATH_X_M = (1.0, 15.0)   # patches lie fully inside this x span [m]
PUDDLE_PATH_HALF_WIDTH_M = 1.0  # ... and inside |y| < this [m]
PUDDLE_COUNT = 8
# A puddle is a box whose top is 1 mm above the floor. Measured (MuJoCo 4.0.0, this model): a loaded
# foot sinks 0.17 mm into the floor standing and at most 0.55 mm into a puddle while landing on it, so a
# foot fully on a puddle touches only the puddle and gets μ = 0.4 (a foot half on it touches both, as a
# real foot would). Priority 2 > floor priority 1 makes MuJoCo use the puddle's friction for every
# contact with it. Tripping: a foot-sized box dragged at 0.3 m/s slides over a 1 mm edge but is stopped
# by a 2 mm one (box-box contact normal turns horizontal), hence 1 mm (tests/test_scenarios.py).
PUDDLE_TOP_M = 0.001
PUDDLE_HALF_DEPTH_M = 0.005     # the box reaches below the floor; world-world pairs never collide
PUDDLE_PRIORITY = 2

# pushes: torso impulses along the walking direction, forward or backward --------------------------------
# A firm shove: 10-25 N·s on the 31.6 kg robot is a 0.3-0.8 m/s velocity change (Playground kicks
# 0.1-1.0 m/s); e.g. 100-250 N held for 0.1 s.
PUSH_IMPULSE_NS = (10.0, 25.0)
PUSH_FIRST_S = 3.0              # first push [s]: time to get walking
PUSH_INTERVAL_S = (4.0, 6.0)    # time between pushes [s]
PUSH_HORIZON_S = 60.0           # schedule length [s]

TORSO_BODY = "Trunk"


@dataclass
class ScenarioInfo:
    name: str
    seed: int
    pushes: list[tuple[float, tuple[float, float, float]]] = field(default_factory=list)
    """(time [s], impulse (x, y, z) [N·s] in the world frame), applied to the torso (Trunk body)."""
    description: str = ""


def add_low_walls(spec: mujoco.MjSpec, first_x_m: float = WALL_FIRST_X_M) -> str:
    """The seed's low-wall course, its first wall's centre plane at x = first_x_m [m] (the evaluation's at
    WALL_FIRST_X_M; the training worlds put theirs far from the origin, training/envs/wall_course.py)."""
    xs = [first_x_m + i * WALL_SPACING_M for i in range(WALL_COUNT)]
    for i, x in enumerate(xs):
        spec.worldbody.add_geom(
            name=f"wall_{i}", type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[WALL_THICKNESS_M / 2, WALL_LENGTH_M / 2, WALL_HEIGHT_M / 2],
            pos=[x, 0.0, WALL_HEIGHT_M / 2], rgba=[0.7, 0.5, 0.3, 1.0])
    return (f"{WALL_COUNT} low walls {WALL_HEIGHT_M} m tall, {WALL_THICKNESS_M} m thick, "
            f"{WALL_LENGTH_M} m long along y, centred at x = {', '.join(f'{x:g}' for x in xs)} m")


def add_tall_wall(spec: mujoco.MjSpec) -> str:
    """A wall taller than the robot across the walking path, for leaning on (supervisor false-alarm tests)."""
    spec.worldbody.add_geom(
        name="tall_wall", type=mujoco.mjtGeom.mjGEOM_BOX,
        size=[TALL_WALL_THICKNESS_M / 2, WALL_LENGTH_M / 2, TALL_WALL_HEIGHT_M / 2],
        pos=[TALL_WALL_FACE_X_M + TALL_WALL_THICKNESS_M / 2, 0.0, TALL_WALL_HEIGHT_M / 2], rgba=[0.6, 0.6, 0.7, 1.0])
    return f"a wall {TALL_WALL_HEIGHT_M} m tall, its face at x = {TALL_WALL_FACE_X_M} m"


def puddle_layout(seed: int) -> list[tuple[float, float, float, float]]:
    """Seeded puddles as (centre x, centre y, side x, side y) [m], non-overlapping, inside the path."""
    rng = np.random.default_rng(seed)
    patches: list[tuple[float, float, float, float]] = []
    tries = 0
    while len(patches) < PUDDLE_COUNT:
        tries += 1
        if tries > 1000:
            raise RuntimeError(f"puddle_layout(seed={seed}): could not place {PUDDLE_COUNT} patches")
        sx, sy = rng.uniform(*PUDDLE_SIDE_M, size=2)
        cx = rng.uniform(PUDDLE_PATH_X_M[0] + sx / 2, PUDDLE_PATH_X_M[1] - sx / 2)
        cy = rng.uniform(-PUDDLE_PATH_HALF_WIDTH_M + sy / 2, PUDDLE_PATH_HALF_WIDTH_M - sy / 2)
        # overlapping boxes would make a 2-puddle seam: keep them apart
        if all(abs(cx - px) > (sx + psx) / 2 or abs(cy - py) > (sy + psy) / 2
               for px, py, psx, psy in patches):
            patches.append((cx, cy, sx, sy))
    return patches


def add_puddle(spec: mujoco.MjSpec, name: str, cx: float, cy: float, sx: float, sy: float) -> None:
    spec.worldbody.add_geom(
        name=name, type=mujoco.mjtGeom.mjGEOM_BOX,
        size=[sx / 2, sy / 2, PUDDLE_HALF_DEPTH_M],
        pos=[cx, cy, PUDDLE_TOP_M - PUDDLE_HALF_DEPTH_M],
        friction=[PUDDLE_FRICTION, 0.005, 0.0001], priority=PUDDLE_PRIORITY, condim=3,
        rgba=[0.3, 0.5, 0.9, 0.8])


def _add_puddles(spec: mujoco.MjSpec, seed: int) -> str:
    layout = puddle_layout(seed)
    for i, (cx, cy, sx, sy) in enumerate(layout):
        add_puddle(spec, f"puddle_{i}", cx, cy, sx, sy)
    return (f"{len(layout)} puddles (μ {PUDDLE_FRICTION}, sides {PUDDLE_SIDE_M[0]}-{PUDDLE_SIDE_M[1]} m) "
            f"on x {PUDDLE_PATH_X_M[0]}-{PUDDLE_PATH_X_M[1]} m, |y| < {PUDDLE_PATH_HALF_WIDTH_M} m")


def push_schedule(seed: int) -> list[tuple[float, tuple[float, float, float]]]:
    """Seeded torso impulses: (time [s], world impulse [N·s]), forward (+x) or backward (-x)."""
    rng = np.random.default_rng(seed)
    pushes = []
    t = PUSH_FIRST_S
    while t < PUSH_HORIZON_S:
        sign = 1.0 if rng.random() < 0.5 else -1.0
        magnitude = rng.uniform(*PUSH_IMPULSE_NS)
        pushes.append((float(t), (sign * float(magnitude), 0.0, 0.0)))
        t += rng.uniform(*PUSH_INTERVAL_S)
    return pushes


def build_spec(name: str, seed: int = 0) -> tuple[mujoco.MjSpec, ScenarioInfo]:
    """The uncompiled spec (for callers that add more, e.g. test objects) and its ScenarioInfo."""
    if name not in SCENARIOS:
        raise ValueError(f"unknown scenario {name!r}; valid: {', '.join(SCENARIOS)}")
    spec = robot_spec()
    pushes: list = []
    if name == "flat":
        description = "flat floor, μ 0.6"
    elif name == "walls":
        description = add_low_walls(spec)
    elif name == "puddles":
        description = _add_puddles(spec, seed)
    elif name == "tall_wall":
        description = add_tall_wall(spec)
    else:
        pushes = push_schedule(seed)
        description = (f"flat floor + {len(pushes)} torso impulses of {PUSH_IMPULSE_NS[0]}-"
                       f"{PUSH_IMPULSE_NS[1]} N·s along ±x every {PUSH_INTERVAL_S[0]}-{PUSH_INTERVAL_S[1]} s")
    return spec, ScenarioInfo(name=name, seed=seed, pushes=pushes, description=description)


def build(name: str, seed: int = 0) -> tuple[mujoco.MjModel, ScenarioInfo]:
    spec, info = build_spec(name, seed)
    return spec.compile(), info

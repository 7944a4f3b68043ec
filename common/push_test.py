"""The loop's push test, drawn: which way, how hard and when the Trunk is shoved in trial `index`. One
definition for the HIL evaluation (sim_hil/eval/plans.py) and the batch's copy of the test
(training/envs/starts/push.py push_test_bank, TorsoShove)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

PUSH_IMPULSE_NS = 40.0          # 1.3 m/s on 31.6 kg: enough to knock a standing T1 over (judgement)
PUSH_AT_S = 2.0                 # 0.1 s PREPARE + ~2 s standing under the policy
# Lockstep trials are deterministic, so the seed varies the push as a hand push varies (the seed's pushes
# were by hand): the impulse within ± this fraction, its direction within ± this angle off the x axis
# [rad], and its time within this window [s] after PUSH_AT_S.
PUSH_IMPULSE_SPREAD = 0.15
PUSH_ANGLE_SPREAD_RAD = 0.26    # ≈ 15°
PUSH_TIME_SPREAD_S = 0.5


@dataclass(frozen=True)
class PushDraw:
    forward: bool
    impulse_ns: float     # [N·s] on the Trunk
    angle_rad: float      # direction off the robot's heading (standing spawns face +x): forward ≈ 0, backward ≈ π
    at_s: float           # [s] after the trial's start


def push_draw(index: int, seed: int) -> PushDraw:
    """Trial `index`'s push, drawn from `seed`: F F B repeated, so any prefix (--trials N) has both directions
    in the 2:1 ratio of 20 forward, 10 back. Also the batch's copy of this test (training/envs/starts/push.py
    push_test_bank)."""
    forward = index % 3 != 2
    rng = np.random.default_rng(seed)
    impulse = PUSH_IMPULSE_NS * (1.0 + rng.uniform(-PUSH_IMPULSE_SPREAD, PUSH_IMPULSE_SPREAD))
    angle = rng.uniform(-PUSH_ANGLE_SPREAD_RAD, PUSH_ANGLE_SPREAD_RAD) + (0.0 if forward else math.pi)
    return PushDraw(forward, impulse, angle, PUSH_AT_S + rng.uniform(0.0, PUSH_TIME_SPREAD_S))

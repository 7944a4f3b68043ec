"""THE definitions of "fall", "getup attempt", "success", "time to stand" and the kneel over a time series.

One module, numpy only (no jax, no LCM; the kneel gate also takes `xp`, so the getup rewards evaluate the same
function under jax), so the MJX batch evaluator (training/) and the HIL evaluation (sim_hil/eval) count the same
events from the same kind of signals: trunk height [m] (Trunk origin = IMU above the floor) and up_z (world z
component of the Trunk's z axis: 1 upright, 0 on its side, -1 upside down; `up_z_from_quat` gets it from the
IMU orientation).

Definitions (one sample = one control tick; the series is read causally, left to right):
- standing: trunk_height >= standing_trunk_threshold_m AND up_z >= upright_up_z.
- stood up: a run of standing samples lasting at least stand_hold_s; the robot stood up at the FIRST sample
  of that run (so time to stand does not include the hold used to confirm it).
- down: the robot is down from the first sample with trunk_height < fallen_trunk_height_m (or from t[0]
  when the series starts that way) until it stands up. Kneeling, crouching or stumbling above the fallen
  height is not down: only lying on the ground is.
- fall: an entry into down after t[0]. A series that STARTS down (the getup scenario's fallen starts) has
  no fall for that start; falls counts the ones that happen during the series.
- getup attempt: while down, the trunk rises attempt_rise_m above its lowest height since the robot went
  down or since the previous attempt failed. The attempt ends in success (stood up) or fails when the
  trunk drops attempt_rise_m below its highest height during the attempt; the next attempt needs a fresh
  rise of attempt_rise_m from the new low. A stand-up ends the attempt in progress; if the down phase
  had no counted rise yet (a series too coarse to see it), the stand-up itself counts as one. Hysteresis of
  one attempt_rise_m both ways is what keeps wobbling and settling from counting as attempts.
- failed after the switch (with a waist height series): a failed attempt during which the waist reached
  the composite's switch height, so the upright policy had the robot when it dropped back.
- success: the series does not end down (every down phase ended with a stand-up). A series that never
  went down is a success; one whose last stand-up has less than stand_hold_s of data after it is not.
- time_to_stand_s: from the start of the FIRST down phase (t[0] for a fallen start, else the first fall
  time) to its stand-up; nan if the robot never went down or never stood up from it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from messages import contract

# The heights are the contract's (messages/contract.json, one meaning each) [m]: Trunk origin below
# FALLEN_TRUNK_HEIGHT_M = lying on the ground; at or above STANDING_TRUNK_THRESHOLD_M (and upright) = standing,
# below the nominal standing height to leave room for a bent-knee stance, yet above kneeling.
FALLEN_TRUNK_HEIGHT_M = contract.FALLEN_TRUNK_HEIGHT_M
STANDING_TRUNK_THRESHOLD_M = contract.STANDING_TRUNK_THRESHOLD_M
UPRIGHT_UP_Z = 0.9          # cos(25.8 deg): trunk tilt that still counts as upright
STAND_HOLD_S = 1.0          # a stand must last this long to count (a stumble through the threshold does not)
# Lying trunk height is ~0.1-0.25 m, kneeling ~0.4-0.5 m: 0.15 m is a clear push off the ground (sitting
# up, rolling onto the knees) but more than the bounce of a body settling after impact (a few cm).
ATTEMPT_RISE_M = 0.15
# The seed's kneel gate (§4.8; training/envs/getup_rewards.py rewards on these same numbers): trunk height
# H − min(h, H) < 0.005 m (H the contract's kneel_gate_height_m, 0.4 m) and ‖u − e_z‖ < 0.01, u the
# trunk's up vector, so ‖u − e_z‖ = √(2 − 2·u_z).
KNEEL_GATE_HEIGHT_M = contract.KNEEL_GATE_HEIGHT_M   # the Trunk origin's [m]
KNEEL_GATE_HEIGHT_TOL_M = contract.KNEEL_GATE_HEIGHT_TOL_M
KNEEL_GATE_UP_ERROR = contract.KNEEL_GATE_UP_ERROR
# The kneel band (ours): the gate's height with ‖u − e_z‖ < 0.05 (≈ 2.9°), the rise → stand hand-over a real IMU and a
# memoryless student can resolve (the chain may hand over at either; kneel_gate's up_error_max).
KNEEL_BAND_UP_ERROR = contract.KNEEL_BAND_UP_ERROR
# The kneeling posture stage 1 must meet the gate in (ours: the gate alone is also met by a crouch or a half kneel):
# both knees at least this flexed and neither hip more flexed than this (a half kneel's forward hip is near
# −1.5 rad) [rad]; the kneel keyframe has knees 1.9, hips −0.2.
KNEEL_KNEE_MIN_RAD = 1.5
KNEEL_HIP_MIN_RAD = -0.6
KNEEL_HOLD_S = 1.0          # stage 1's kneel counts as held once the gate has held this long in the posture
# How a fallen start lies, from the world z of the trunk's forward (x) axis (common.model.trunk_forward_z): below
# −FACING_Z face down, above +FACING_Z on the back, else on its side.
FACING_Z = contract.LYING_FACING_Z
LYING_SIDES = ("face_down", "on_back", "side")
# The roll's hand-over to the face-down rise (the keyframe getup's chain roll → rise → stand): lying (trunk below
# the fallen height), turned face down well past the lying-side rule's edge (forward z below −ROLLED_FORWARD_Z)
# and no longer tumbling (trunk angular speed below ROLLED_MAX_ANG_SPEED_RAD_S), as the rise's face-down starts lie.
ROLLED_FORWARD_Z = contract.ROLLED_FORWARD_Z
ROLLED_MAX_ANG_SPEED_RAD_S = contract.ROLLED_MAX_ANG_SPEED_RAD_S
KNEE_PITCHES = ("Left_Knee_Pitch", "Right_Knee_Pitch")
HIP_PITCHES = ("Left_Hip_Pitch", "Right_Hip_Pitch")


@dataclass(frozen=True)
class EventThresholds:
    fallen_trunk_height_m: float = FALLEN_TRUNK_HEIGHT_M
    standing_trunk_threshold_m: float = STANDING_TRUNK_THRESHOLD_M
    upright_up_z: float = UPRIGHT_UP_Z
    stand_hold_s: float = STAND_HOLD_S
    attempt_rise_m: float = ATTEMPT_RISE_M

    def __post_init__(self):
        for name in ("fallen_trunk_height_m", "standing_trunk_threshold_m", "upright_up_z",
                     "stand_hold_s", "attempt_rise_m"):
            value = getattr(self, name)
            if not math.isfinite(value):
                raise ValueError(f"EventThresholds.{name} must be finite, got {value!r}")
        if self.standing_trunk_threshold_m <= self.fallen_trunk_height_m:
            raise ValueError(f"EventThresholds: standing_trunk_threshold_m ({self.standing_trunk_threshold_m}) "
                             f"must be above fallen_trunk_height_m ({self.fallen_trunk_height_m})")
        if self.stand_hold_s < 0 or self.attempt_rise_m <= 0:
            raise ValueError("EventThresholds: stand_hold_s must be >= 0 and attempt_rise_m > 0")
        if not -1.0 <= self.upright_up_z <= 1.0:
            raise ValueError(f"EventThresholds.upright_up_z must lie in [-1, 1], got {self.upright_up_z}")


class Attempt(NamedTuple):
    """One getup attempt of GetupEvents.attempt_log (definitions: module docstring)."""
    start_s: float        # the sample at which the trunk had risen attempt_rise_m [s]
    end_s: float          # where it failed or stood up [s]; nan while still open at the series' end
    outcome: str          # "failed", "stood" or "open"
    peak_trunk_m: float   # the highest trunk height during the attempt [m]
    switched: bool        # the waist reached the switch height during it (False without a waist series)


@dataclass(frozen=True)
class GetupEvents:
    success: bool
    time_to_stand_s: float            # nan: never down, or never stood up from the first down phase
    attempts: int
    falls: int
    fall_times_s: list[float] = field(default_factory=list)
    started_down: bool = False        # down from t[0] (a fallen start): a down phase that is not a fall
    # failed attempts during which the waist reached the composite's switch height (the upright policy had
    # the robot when it dropped back); None when getup_events got no waist series
    failed_after_switch: int | None = None
    attempt_log: list[Attempt] = field(default_factory=list)   # one entry per counted attempt, in order


def heading_from_quat(quat_wxyz) -> float:
    """Heading [rad] in (−π, π] of a body with quaternion (w x y z): the yaw of its x axis about world z."""
    w, x, y, z = (float(c) for c in quat_wxyz)
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def up_z_from_quat(quat_wxyz) -> np.ndarray:
    """World z of the body z axis from (..., 4) quaternions (w x y z): 1 - 2(x² + y²)."""
    q = np.asarray(quat_wxyz, dtype=np.float64)
    if q.shape[-1] != 4:
        raise ValueError(f"up_z_from_quat: last axis must be 4 (w x y z), got shape {q.shape}")
    norm2 = np.sum(q * q, axis=-1)
    if np.any(norm2 <= 0) or not np.all(np.isfinite(norm2)):
        raise ValueError("up_z_from_quat: zero or non-finite quaternion")
    return 1.0 - 2.0 * (q[..., 1] ** 2 + q[..., 2] ** 2) / norm2


def _series(name: str, values, n: int | None = None) -> np.ndarray:
    a = np.asarray(values, dtype=np.float64)
    if a.ndim != 1:
        raise ValueError(f"{name} must be 1-D (one value per tick), got shape {a.shape}")
    if n is not None and a.shape[0] != n:
        raise ValueError(f"{name} has {a.shape[0]} samples, t has {n}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains non-finite values (first at index {int(np.argmin(np.isfinite(a)))})")
    return a


def standing_mask(trunk_height, up_z, th: EventThresholds = EventThresholds()) -> np.ndarray:
    """Per-sample standing test (no hold time): tall enough and upright enough."""
    h = np.asarray(trunk_height, dtype=np.float64)
    u = np.asarray(up_z, dtype=np.float64)
    if h.shape != u.shape:
        raise ValueError(f"standing_mask: trunk_height shape {h.shape} != up_z shape {u.shape}")
    return (h >= th.standing_trunk_threshold_m) & (u >= th.upright_up_z)


def at_kneel_gate_height(trunk_height, xp=np):
    """The kneel gate's height condition (§4.8): H − min(h, H) < 0.005 m, trunk height h [m], H = KNEEL_GATE_HEIGHT_M.
    xp: numpy or jax.numpy (the getup rewards read the same definition under jit)."""
    return KNEEL_GATE_HEIGHT_M - xp.minimum(trunk_height, KNEEL_GATE_HEIGHT_M) < KNEEL_GATE_HEIGHT_TOL_M


def kneel_gate(trunk_height, up_z, xp=np, up_error_max: float = KNEEL_GATE_UP_ERROR):
    """The seed's kneel gate (§4.8) per sample: at its height and ‖u − e_z‖ = √(2 − 2·u_z) < 0.01, from trunk
    height [m] and up_z. xp: numpy or jax.numpy, as common/observation.py's functions. up_error_max: a looser
    upright condition (a distillation's hand-over of labels), the gate's own by default."""
    up_error = xp.sqrt(xp.maximum(2.0 - 2.0 * up_z, 0.0))
    return at_kneel_gate_height(trunk_height, xp) & (up_error < up_error_max)


def kneel_gate_mask(trunk_height, up_z) -> np.ndarray:
    """kneel_gate over a float64 series (the evaluations' reading of recorded signals)."""
    return kneel_gate(np.asarray(trunk_height, dtype=np.float64), np.asarray(up_z, dtype=np.float64))


def gate_while_standing(trunk_height, up_z) -> float:
    """The share of the standing samples at which §4.8's gate holds (nan if none stands): where the full task's
    per-step gate pays a standing robot the standing rewards rather than the kneel's."""
    standing = standing_mask(trunk_height, up_z)
    return float(kneel_gate_mask(trunk_height, up_z)[standing].mean()) if standing.any() else math.nan


def kneeling_posture(q, xp=np, knee_min_rad: float = KNEEL_KNEE_MIN_RAD, hip_min_rad: float = KNEEL_HIP_MIN_RAD):
    """Per sample: the double kneel, from joint angles q [..., 23] in contract order [rad]. xp: numpy or jax.numpy."""
    knees = [contract.joint_index(n) for n in KNEE_PITCHES]
    hips = [contract.joint_index(n) for n in HIP_PITCHES]
    return xp.all(q[..., knees] >= knee_min_rad, axis=-1) & xp.all(q[..., hips] >= hip_min_rad, axis=-1)


def lying_side(forward_z: float) -> str:
    """face_down | on_back | side, from the world z of the trunk's forward axis."""
    return "face_down" if forward_z < -FACING_Z else "on_back" if forward_z > FACING_Z else "side"


def forward_z_from_quat(quat_wxyz, xp=np):
    """World z of the body's forward (x) axis from (..., 4) quaternions (w x y z): 2(xz − wy); near −1 lying face
    down, near +1 on the back. xp: numpy or jax.numpy."""
    q = xp.asarray(quat_wxyz)
    return 2.0 * (q[..., 1] * q[..., 3] - q[..., 0] * q[..., 2])


def rolled_face_down(forward_z, trunk_height, ang_speed_rad_s, xp=np):
    """Per sample: the roll has handed over to the face-down rise (the constants above say when). xp: numpy or
    jax.numpy, so training, the chain's switch and the evaluations read one rule."""
    return ((xp.asarray(forward_z) < -ROLLED_FORWARD_Z) & (xp.asarray(trunk_height) < FALLEN_TRUNK_HEIGHT_M)
            & (xp.asarray(ang_speed_rad_s) < ROLLED_MAX_ANG_SPEED_RAD_S))


def lying_back_or_side(forward_z, trunk_height, ang_speed_rad_s, xp=np):
    """Per sample: lying still, not face down (the lying-side rule's on_back or side, trunk below the fallen
    height): a rise that tipped over backwards or sideways hands the robot back to the roll (the rise learnt only
    from face-down starts; on its side it lay still)."""
    return ((xp.asarray(forward_z) > -FACING_Z) & (xp.asarray(trunk_height) < FALLEN_TRUNK_HEIGHT_M)
            & (xp.asarray(ang_speed_rad_s) < ROLLED_MAX_ANG_SPEED_RAD_S))


KEYFRAME_STAGES = ("roll", "rise", "stand")   # the keyframe getup's chain, in order (keyframe_stage's indices)
KEYFRAME_START = -1                            # keyframe_stage's `stage` at an episode's first sample


def keyframe_stage(stage, forward_z, trunk_height, up_z, ang_speed_rad_s, xp=np,
                   handover_up_error: float = KNEEL_GATE_UP_ERROR):
    """The chain stage (KEYFRAME_STAGES index) that acts at this sample, from the one that acted at the last: roll
    until rolled_face_down, rise until §4.8's gate (back to roll if it tipped the robot onto its back or side), stand
    until the trunk is down (then roll again). At KEYFRAME_START the trunk's height picks the first: lying, roll
    (the rise if already face down); above the fallen height, the rise; standing, stand. xp: numpy or jax.numpy.
    handover_up_error: the rise hands over at the gate with this upright condition (kneel_gate's up_error_max)."""
    roll_, rise_, stand_ = range(len(KEYFRAME_STAGES))
    h = xp.asarray(trunk_height)
    first = xp.where(h < FALLEN_TRUNK_HEIGHT_M, roll_, xp.where(h < STANDING_TRUNK_THRESHOLD_M, rise_, stand_))
    stage = xp.where(xp.asarray(stage) == KEYFRAME_START, first, stage)
    roll = xp.where(rolled_face_down(forward_z, h, ang_speed_rad_s, xp), rise_, roll_)
    rise = xp.where(kneel_gate(h, up_z, xp, handover_up_error), stand_,
                    xp.where(lying_back_or_side(forward_z, h, ang_speed_rad_s, xp), roll_, rise_))
    stand = xp.where(h < FALLEN_TRUNK_HEIGHT_M, roll_, stand_)
    return xp.where(stage == roll_, roll, xp.where(stage == rise_, rise, stand)).astype(xp.int32)


def longest_run(flags) -> int:
    """The most samples in a row that hold (0: none)."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], np.asarray(flags, bool).astype(np.int8), [0]])))
    edges = edges.reshape(-1, 2)
    return int((edges[:, 1] - edges[:, 0]).max(initial=0))


def kneel_hold_s(trunk_height, up_z, kneeling, dt: float) -> float:
    """The longest run of samples dt [s] apart in which §4.8's gate held in the kneeling posture, as a time:
    k samples in a row hold k·dt [s] (0: never)."""
    return float(longest_run(kneel_gate_mask(trunk_height, up_z) & np.asarray(kneeling, bool)) * dt)


def reached_kneel(trunk_height, up_z, th: EventThresholds = EventThresholds()) -> bool:
    """Whether the trunk met the kneel gate at a sample that does not count as standing: the kneeling posture
    of the seed's stage 1 (fallen → kneel), whatever came after."""
    h, u = np.asarray(trunk_height, dtype=np.float64), np.asarray(up_z, dtype=np.float64)
    return bool(np.any(kneel_gate_mask(h, u) & ~standing_mask(h, u, th)))


def through_kneel_gate(t, trunk_height, up_z, events: GetupEvents, th: EventThresholds = EventThresholds(),
                       kneeling=None, up_error_max: float = KNEEL_GATE_UP_ERROR) -> bool | None:
    """Whether the trunk met the kneel gate on its way up: at a sample that does not count as standing,
    between the start of the first down phase and its stand-up (a keyframe getup rises through the kneel;
    any upright stand meets the gate, so standing samples do not count). None when it never
    stood up from that phase. With `kneeling` (per sample, kneeling_posture), only in the kneeling posture;
    up_error_max: the gate's upright bound (KNEEL_BAND_UP_ERROR: through the kneel band)."""
    if math.isnan(events.time_to_stand_s):
        return None
    t, h, u = (np.asarray(x, dtype=np.float64) for x in (t, trunk_height, up_z))
    first_down = t[0] if h[0] < th.fallen_trunk_height_m else events.fall_times_s[0]
    rising = (t >= first_down) & (t < first_down + events.time_to_stand_s) & ~standing_mask(h, u, th)
    if kneeling is not None:
        rising &= np.asarray(kneeling, bool)
    return bool(np.any(kneel_gate(h[rising], u[rising], np, up_error_max)))


def _stand_up_onsets(t: np.ndarray, standing: np.ndarray, hold_s: float) -> np.ndarray:
    """is_onset[i]: sample i starts a standing run that lasts >= hold_s (judged on the samples present)."""
    n = len(t)
    onset = np.zeros(n, dtype=bool)
    i = 0
    while i < n:
        if not standing[i]:
            i += 1
            continue
        j = i
        while j + 1 < n and standing[j + 1]:
            j += 1
        # Every sample of the run that still has hold_s of standing ahead of it could be where the
        # robot stood up (a run may begin while the robot is not yet down, e.g. before a fall).
        last_start = np.searchsorted(t[i:j + 1], t[j] - hold_s, side="right") - 1
        if last_start >= 0:
            onset[i:i + last_start + 1] = True
        i = j + 1
    return onset


def getup_events(t, trunk_height, up_z, th: EventThresholds = EventThresholds(), waist_height=None,
                 switch_height_m: float = math.inf) -> GetupEvents:
    """Falls, getup attempts, success and time to stand of one episode (definitions: module docstring). With
    a waist height series [m], also the failed attempts during which it reached switch_height_m."""
    t = _series("t", t)
    n = t.shape[0]
    if n == 0:
        raise ValueError("getup_events: empty time series")
    if n > 1 and not np.all(np.diff(t) > 0):
        raise ValueError("getup_events: t must be strictly increasing")
    h = _series("trunk_height", trunk_height, n)
    u = _series("up_z", up_z, n)
    above = None if waist_height is None else (_series("waist_height", waist_height, n) >= switch_height_m).tolist()

    can_stand_up = _stand_up_onsets(t, standing_mask(h, u, th), th.stand_hold_s)
    lying = h < th.fallen_trunk_height_m

    down = False
    falls: list[float] = []
    attempts = 0
    first_down_t = math.nan
    time_to_stand = math.nan
    low = high = 0.0          # lowest height while waiting for a rise / highest during an attempt [m]
    in_attempt = False
    attempts_this_phase = 0
    failed_after_switch, switched = 0, False
    log: list[Attempt] = []
    start_s = math.nan
    t_list, h, lying, can_stand_up = t.tolist(), h.tolist(), lying.tolist(), can_stand_up.tolist()
    for k in range(n):
        if not down:
            if lying[k]:
                down = True
                if k > 0:
                    falls.append(t_list[k])
                if math.isnan(first_down_t):
                    first_down_t = t_list[k]
                low, in_attempt, attempts_this_phase = h[k], False, 0
            continue
        if can_stand_up[k]:
            if attempts_this_phase == 0:
                attempts += 1         # stood up between two samples (coarse series): still one attempt
                attempts_this_phase = 1
                log.append(Attempt(t_list[k], t_list[k], "stood", h[k], bool(above and above[k])))
            elif in_attempt:
                log.append(Attempt(start_s, t_list[k], "stood", max(high, h[k]), switched))
            in_attempt = False
            down = False
            if math.isnan(time_to_stand):
                time_to_stand = t_list[k] - first_down_t
            continue
        if in_attempt:
            high = max(high, h[k])
            switched = switched or bool(above and above[k])
            if h[k] <= high - th.attempt_rise_m:
                in_attempt, low = False, h[k]
                failed_after_switch += switched
                log.append(Attempt(start_s, t_list[k], "failed", high, switched))
        else:
            low = min(low, h[k])
            if h[k] >= low + th.attempt_rise_m:
                in_attempt, high, switched = True, h[k], bool(above and above[k])
                start_s = t_list[k]
                attempts += 1
                attempts_this_phase += 1
    if in_attempt and down:
        log.append(Attempt(start_s, math.nan, "open", high, switched))
    return GetupEvents(success=not down, time_to_stand_s=time_to_stand, attempts=attempts,
                       falls=len(falls), fall_times_s=falls, started_down=bool(lying[0]),
                       failed_after_switch=None if above is None else failed_after_switch, attempt_log=log)

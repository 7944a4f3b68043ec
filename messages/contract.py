"""Joint order and ranges, channel names, the default LCM URL, the loop and policy rates and the heights every layer
shares (fallen, standing, the kneel gate, the composite's waist switch), read from messages/contract.json (the
one source; C++ gets the same values in a header generated at build time)."""
from __future__ import annotations

import json
import os
import re
from pathlib import Path

_DATA = json.loads((Path(__file__).with_name("contract.json")).read_text())

NUM_JOINTS: int = _DATA["num_joints"]
JOINT_NAMES: tuple[str, ...] = tuple(_DATA["joints"])
# Each joint's position range [rad] (lower, upper), joint order: the model's limits and the motors' soft stops.
assert list(_DATA["joint_ranges_rad"]) == list(JOINT_NAMES), \
    "contract.json: joint_ranges_rad must name every joint, in the joints' order"
JOINT_RANGES_RAD: tuple[tuple[float, float], ...] = tuple(
    (float(lo), float(hi)) for lo, hi in _DATA["joint_ranges_rad"].values())
CHANNELS: dict[str, str] = dict(_DATA["channels"])
# channel name -> LCM type name (messages/t1/<type>.lcm), e.g. "T1_IMU" -> "imu_t"
CHANNEL_TYPES: dict[str, str] = {CHANNELS[key]: type_name for key, type_name in _DATA["channel_types"].items()}
DEFAULT_LCM_URL: str = _DATA["lcm_url"]
# The runtime's loop and the policy's rate: one loop tick every LOOP_PERIOD_S (500 Hz), the policy every
# POLICY_DECIMATION-th tick, POLICY_PERIOD_S apart (50 Hz): every artifact's control_dt, the training envs' step.
LOOP_PERIOD_S: float = float(_DATA["loop_period_s"])
POLICY_DECIMATION: int = int(_DATA["policy_decimation"])
POLICY_PERIOD_S: float = LOOP_PERIOD_S * POLICY_DECIMATION
LOOP_RATE_HZ: float = 1.0 / LOOP_PERIOD_S
POLICY_RATE_HZ: float = 1.0 / POLICY_PERIOD_S
# Heights above the floor [m] (contract.json "_heights_comment" has each one's meaning).
FALLEN_TRUNK_HEIGHT_M: float = float(_DATA["fallen_trunk_height_m"])            # Trunk below: lying
STANDING_TRUNK_THRESHOLD_M: float = float(_DATA["standing_trunk_threshold_m"])  # Trunk at or above (upright): standing
NOMINAL_STANDING_TRUNK_HEIGHT_M: float = float(_DATA["nominal_standing_trunk_height_m"])   # home pose, standing
STANDING_TARGET_TRUNK_M: float = float(_DATA["standing_target_trunk_m"])   # getup Height Reward's targets after
STANDING_TARGET_WAIST_M: float = float(_DATA["standing_target_waist_m"])   # the kneel gate
KNEEL_GATE_HEIGHT_M: float = float(_DATA["kneel_gate_height_m"])    # the kneel gate's Trunk height
# The rise → stand hand-overs (contract.json "_kneel_comment"): the gate's height tolerance [m] and the upright
# bounds ‖u − e_z‖ of §4.8's gate and of the looser kneel band.
KNEEL_GATE_HEIGHT_TOL_M: float = float(_DATA["kneel_gate_height_tol_m"])
KNEEL_GATE_UP_ERROR: float = float(_DATA["kneel_gate_up_error"])
KNEEL_BAND_UP_ERROR: float = float(_DATA["kneel_band_up_error"])
# The chain's other hand-overs (contract.json "_lying_comment"): the lying-side rule's bound on the Trunk's forward
# z, the roll's face-down bound and the Trunk's angular speed below which a lying robot is still [rad/s].
LYING_FACING_Z: float = float(_DATA["lying_facing_z"])
ROLLED_FORWARD_Z: float = float(_DATA["rolled_forward_z"])
ROLLED_MAX_ANG_SPEED_RAD_S: float = float(_DATA["rolled_max_ang_speed_rad_s"])
# The composite's switch [m]: getup member below this Waist height, upright member at or above it.
WAIST_SWITCH_HEIGHT_M: float = float(_DATA["waist_switch_height_m"])
# The supervisor's behaviour training models (contract.json "supervisor"): PREPARE's ramp [s] and stand-up gains
# per joint, joint order (kp [N·m/rad], kd [N·m·s/rad]), and rule R6's target rate limit [rad/s] and range fraction.
_SUPERVISOR = _DATA["supervisor"]
assert list(_SUPERVISOR["prepare"]["gains"]) == list(JOINT_NAMES), \
    "contract.json: supervisor.prepare.gains must name every joint, in the joints' order"
PREPARE_DURATION_S: float = float(_SUPERVISOR["prepare"]["duration_s"])
PREPARE_KP_NM_PER_RAD: tuple[float, ...] = tuple(float(kp) for kp, _ in _SUPERVISOR["prepare"]["gains"].values())
PREPARE_KD_NMS_PER_RAD: tuple[float, ...] = tuple(float(kd) for _, kd in _SUPERVISOR["prepare"]["gains"].values())
R6_MAX_TARGET_SPEED_RPS: float = float(_SUPERVISOR["r6"]["max_target_speed_rps"])
R6_JOINT_RANGE_FRACTION: float = float(_SUPERVISOR["r6"]["joint_range_fraction"])
# Who may command (messages/auth.py): the channels whose messages are signed, the approval context, the key size.
AUTH: dict = {k: v for k, v in _DATA["auth"].items() if not k.startswith("_")}
# The real T1's DDS interface: domain_id, state_topic, command_topic, cmd_type_serial, motor_mode, motor_weight.
DDS: dict = {k: v for k, v in _DATA["dds"].items() if not k.startswith("_")}

CH_IMU = CHANNELS["imu"]
CH_JOINT_STATE = CHANNELS["joint_state"]
CH_JOINT_CMD = CHANNELS["joint_cmd"]
CH_JOYSTICK = CHANNELS["joystick"]
CH_RUNTIME_CMD = CHANNELS["runtime_cmd"]
CH_CONTROLLER_STATUS = CHANNELS["controller_status"]
CH_OBS = CHANNELS["obs"]
CH_ACTION = CHANNELS["action"]
CH_SIM_STATUS = CHANNELS["sim_status"]
CH_RUN_INFO = CHANNELS["run_info"]

assert len(JOINT_NAMES) == NUM_JOINTS, "contract.json: joints list length differs from num_joints"
assert all(lo < hi for lo, hi in JOINT_RANGES_RAD), "contract.json: each joint range is (lower, upper), lower < upper"
assert set(_DATA["channel_types"]) == set(CHANNELS), "contract.json: channel_types must name every channel"
assert POLICY_DECIMATION >= 1 and LOOP_PERIOD_S > 0, "contract.json: loop_period_s > 0, policy_decimation >= 1"
assert 0 < FALLEN_TRUNK_HEIGHT_M < KNEEL_GATE_HEIGHT_M < STANDING_TRUNK_THRESHOLD_M \
    < NOMINAL_STANDING_TRUNK_HEIGHT_M, "contract.json: heights must order fallen < kneel gate < standing < nominal"
assert 0 < KNEEL_GATE_UP_ERROR < KNEEL_BAND_UP_ERROR < 2 and KNEEL_GATE_HEIGHT_TOL_M > 0, \
    "contract.json: 0 < kneel_gate_up_error < kneel_band_up_error < 2, kneel_gate_height_tol_m > 0"


def lcm_url() -> str:
    """The LCM URL to use: $T1_LCM_URL (set by tools/netns) or the contract default (ttl=0)."""
    return os.environ.get("T1_LCM_URL", DEFAULT_LCM_URL)


def lcm_url_on_port(offset: int, base: str | None = None) -> str:
    """`base` (default: lcm_url()) with its port moved by `offset`, options (ttl) kept: a private bus for a
    parallel evaluation worker, a replay or an echo next to the contract's one."""
    base = base or lcm_url()
    m = re.match(r"^(udpm://[^:/?]+):(\d+)(.*)$", base)
    if not m:
        raise ValueError(f"LCM URL {base!r}: expected udpm://GROUP:PORT[?options]")
    return f"{m.group(1)}:{int(m.group(2)) + offset}{m.group(3)}"


def joint_index(name: str) -> int:
    return JOINT_NAMES.index(name)

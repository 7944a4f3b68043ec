"""Joint order, channel names, the default LCM URL and the composite's waist switch height, read from messages/contract.json (the one source;
C++ gets the same values in a header generated at build time)."""
from __future__ import annotations

import json
import os
import re
from pathlib import Path

_DATA = json.loads((Path(__file__).with_name("contract.json")).read_text())

NUM_JOINTS: int = _DATA["num_joints"]
JOINT_NAMES: tuple[str, ...] = tuple(_DATA["joints"])
CHANNELS: dict[str, str] = dict(_DATA["channels"])
# channel name -> LCM type name (messages/t1/<type>.lcm), e.g. "T1_IMU" -> "imu_t"
CHANNEL_TYPES: dict[str, str] = {CHANNELS[key]: type_name for key, type_name in _DATA["channel_types"].items()}
DEFAULT_LCM_URL: str = _DATA["lcm_url"]
# The composite's switch [m]: getup member below this Waist height, upright member at or above it.
WAIST_SWITCH_HEIGHT_M: float = float(_DATA["waist_switch_height_m"])
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
assert set(_DATA["channel_types"]) == set(CHANNELS), "contract.json: channel_types must name every channel"


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

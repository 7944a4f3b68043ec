"""The robot maker's own client against `python -m sim_hil --dds --fastdds-compat`: the Booster SDK's
B1LowStateSubscriber reads the simulated T1's state and its B1LowCmdPublisher turns the head (SERIAL,
CUSTOM-mode fields as booster_gym's deploy fills them). Run as a child process by
tests/test_dds_booster_sdk.py (inside tools/netns); prints one JSON line.

    python -m tests.booster_sdk_client TARGET_OFFSET_RAD
"""
from __future__ import annotations

import json
import sys
import time

import booster_robotics_sdk_python as sdk

from messages import contract

N = contract.NUM_JOINTS
HEAD_YAW = contract.joint_index("AAHead_yaw")
KP, KD = 20.0, 1.0            # head gains [N·m/rad, N·m·s/rad], inside the motor frame's range
COMMAND_PERIOD_S = 0.01       # 100 Hz: well inside the motors' 50 ms command watchdog
COMMAND_S = 1.5               # how long the head target is held
FIRST_STATE_TIMEOUT_S = 20.0  # liveness bound (discovery), not a timing check


def main() -> None:
    offset = float(sys.argv[1])
    sdk.ChannelFactory.Instance().Init(contract.DDS["domain_id"], "lo")
    states: list[list[float]] = []
    sub = sdk.B1LowStateSubscriber(lambda m: states.append([s.q for s in m.motor_state_serial]))
    sub.InitChannel()
    pub = sdk.B1LowCmdPublisher()
    pub.InitChannel()
    deadline = time.monotonic() + FIRST_STATE_TIMEOUT_S
    while not states and time.monotonic() < deadline:
        time.sleep(COMMAND_PERIOD_S)
    if not states:
        print(json.dumps({"states": 0}))
        return
    first = list(states[-1])
    cmd = sdk.LowCmd()
    cmd.cmd_type = sdk.LowCmdType.SERIAL
    motors = [sdk.MotorCmd() for _ in range(N)]
    for i, m in enumerate(motors):
        m.q, m.dq, m.tau, m.kp, m.kd, m.weight = first[i], 0.0, 0.0, KP, KD, contract.DDS["motor_weight"]
    motors[HEAD_YAW].q = first[HEAD_YAW] + offset
    cmd.motor_cmd = motors
    end = time.monotonic() + COMMAND_S
    while time.monotonic() < end:
        pub.Write(cmd)
        time.sleep(COMMAND_PERIOD_S)
    print(json.dumps({"states": len(states), "motors": len(states[-1]), "head_yaw_first": first[HEAD_YAW],
                      "head_yaw_last": states[-1][HEAD_YAW]}), flush=True)
    # Closed before the interpreter tears the SDK down: a state callback still running into that teardown
    # segfaulted the client now and then, after its result was out.
    sub.CloseChannel()
    pub.CloseChannel()


if __name__ == "__main__":
    main()

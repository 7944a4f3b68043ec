"""The real client: the Booster SDK (booster-robotics-sdk-python 1.6.3, Fast DDS inside; a
test-only dependency) talks to `python -m sim_hil --dds` as to a T1. Its B1LowStateSubscriber receives the
simulated state and its B1LowCmdPublisher moves the simulated robot.

Needs --fastdds-compat (sim_hil/fastdds_shim.py): without it the SDK's Fast DDS drops Cyclone's participant
announcement (it misreads Cyclone's vendor parameter 0x8007) and nothing ever matches."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from sim_hil.launch import ROOT, _env, start_sim, stop

pytest.importorskip("booster_robotics_sdk_python")

HEAD_OFFSET_RAD = 0.4
HEAD_TOLERANCE_RAD = 0.1      # PD at kp 20 holds the light head close to its target
CLIENT_TIMEOUT_S = 60.0


@pytest.mark.slow
def test_the_booster_sdk_reads_the_simulated_state_and_moves_the_simulated_robot(netns):
    sim = start_sim("--dds", "--fastdds-compat", "--clock", "realtime", "--spawn", "standing", "--duration", "30")
    try:
        client = subprocess.run([sys.executable, "-m", "tests.booster_sdk_client", str(HEAD_OFFSET_RAD)], cwd=ROOT,
                                env=_env(), capture_output=True, text=True, timeout=CLIENT_TIMEOUT_S)
    finally:
        _, err = stop(sim)   # SIGTERM ends the realtime sim (exit -15): only the client's result counts
    assert client.returncode == 0, client.stderr[-2000:]
    result = json.loads(client.stdout.strip().splitlines()[-1])
    assert result["states"] > 0, f"the SDK received no LowState from sim_hil --dds; sim: {err[-1000:]}"
    assert result["motors"] == 23
    moved = result["head_yaw_last"] - result["head_yaw_first"]
    assert abs(moved - HEAD_OFFSET_RAD) < HEAD_TOLERANCE_RAD, result

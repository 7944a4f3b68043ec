"""The runtime faces a DDS robot. t1-runtime --transport dds against `python -m sim_hil --dds`
(closed loop) and against a test peer writing LowState_ samples itself (malformed samples, damping on
FAULT and on exit). Every process runs inside tools/netns with Cyclone on loopback only (tools/netns
exports CYCLONEDDS_URI)."""
from __future__ import annotations

import math
import time

import lcm
import numpy as np
import pytest
from t1 import controller_status_t, sim_status_t

from common.artifact import read_artifact
from messages import contract
from sim_hil.dds_bridge import rpy_from_quat
from sim_hil.launch import ROOT, start_runtime, start_sim, stop
from tests.dds_peer import DdsRobotPeer, low_state
from tests.runtime_peer import LATCHED_FAULT_MASK, MODE

UNTRAINED_STUDENT = ROOT / "policies" / "student_untrained" / "student_untrained.safetensors"
N = contract.NUM_JOINTS
PREPARE_S = 5.0                 # the robot stands this long under the PREPARE pose before the policy runs
POLICY_S = 3.0
STANDING_TRUNK_MIN_M = 0.55     # Trunk origin above this = still standing (standing: 0.665 m)
TRUNK_MATCH_M = 0.05            # DDS and LCM runs: same trunk height within this (the DDS start-up handshake
                                # may give the runtime's clock a few extra ticks)
LIVENESS_S = 30.0               # bound on waiting for a process (not a timing check)


class LcmWatch:
    """The runtime's T1_CONTROLLER_STATUS and the sim's T1_SIM_STATUS (both stay on LCM)."""

    def __init__(self):
        self.lc = lcm.LCM(contract.lcm_url())
        self.status: list[controller_status_t] = []
        self.sim: list[sim_status_t] = []
        self.lc.subscribe(contract.CH_CONTROLLER_STATUS,
                          lambda _c, d: self.status.append(controller_status_t.decode(d)))
        self.lc.subscribe(contract.CH_SIM_STATUS, lambda _c, d: self.sim.append(sim_status_t.decode(d)))

    def pump_while(self, alive, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while alive() and time.monotonic() < deadline:
            self.lc.handle_timeout(20)
        while self.lc.handle_timeout(50) > 0:
            pass


# ------------------------------------------------------------------------------------ the convention
def test_sim_rpy_is_the_convention_the_runtime_reads():
    """sim_hil writes Z-Y-X rpy; gravity from it, (sin p, -sin r cos p, -cos r cos p) as the runtime
    computes it, equals R(quat)^T (0, 0, -1) for the simulated IMU's quaternion."""
    rng = np.random.default_rng(3)
    for _ in range(100):
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)
        w, x, y, z = quat
        g_quat = -np.array([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])
        r, p, _ = rpy_from_quat(quat)
        g_rpy = np.array([math.sin(p), -math.sin(r) * math.cos(p), -math.cos(r) * math.cos(p)])
        np.testing.assert_allclose(g_rpy, g_quat, atol=1e-9)


# ------------------------------------------------------------------------------------ closed loop
def closed_loop(link: str) -> tuple[LcmWatch, str]:
    """Runtime + sim in lockstep over one robot link (lcm | dds), standing start, PREPARE_S of PREPARE."""
    watch = LcmWatch()
    runtime = start_runtime(UNTRAINED_STUDENT, "--transport", link, "--clock", "lockstep", "--autostart",
                            "--prepare-s", str(PREPARE_S))
    sim = start_sim(*(["--dds"] if link == "dds" else []), "--clock", "lockstep", "--spawn", "standing",
                    "--status-rate", "50", "--duration", str(PREPARE_S + POLICY_S))
    watch.pump_while(lambda: sim.poll() is None, 300)
    assert sim.poll() == 0, f"sim failed: {sim.communicate()[1][-2000:] if sim.poll() is not None else 'timeout'}"
    code, err = stop(runtime)
    assert code == 0, f"runtime exit {code}: {err}"
    return watch, err


def assert_stood_through_prepare(watch: LcmWatch) -> None:
    """Standing start, and the trunk stayed up for all PREPARE_S of PREPARE: the runtime holds the pose with
    the T1's stand-up gains (runtime/include/t1rt/prepare_gains.hpp; with the policy's soft gains a PD hold
    tips this model over after ~1.3 s). The untrained policy that runs afterwards may let it fall."""
    prepare = [s.trunk_height for s in watch.sim if s.utime * 1e-6 <= PREPARE_S]
    assert prepare and prepare[0] > STANDING_TRUNK_MIN_M, "standing start"
    assert watch.sim[-1].utime * 1e-6 >= PREPARE_S, "the run ended before PREPARE did"
    assert min(prepare) > STANDING_TRUNK_MIN_M, f"the robot went down under PREPARE: trunk {min(prepare):.3f} m"


@pytest.mark.slow
def test_lockstep_over_dds_runs_prepare_then_the_policy_without_fault_as_over_lcm(netns):
    watch, err = closed_loop("dds")
    assert "robot link DDS" in err
    modes = [s.mode_name for s in watch.status]
    assert "PREPARE" in modes and modes[-1] == "POLICY", modes[-20:]
    assert all(s.fault_bits & LATCHED_FAULT_MASK == 0 for s in watch.status), watch.status[-1].last_fault
    assert watch.status[-1].policy_ticks > 0
    assert watch.status[-1].decode_errors == 0
    last = watch.sim[-1]
    assert last.cmds_dropped == 0
    assert last.lockstep_timeouts == 0, "a state went unanswered over DDS"
    assert_stood_through_prepare(watch)
    # The same robot over LCM: the transport changes nothing the robot does.
    lcm_watch, _ = closed_loop("lcm")
    assert_stood_through_prepare(lcm_watch)
    by_time = {s.utime: s.trunk_height for s in lcm_watch.sim}
    pairs = [(by_time[s.utime], s.trunk_height) for s in watch.sim if s.utime in by_time]
    assert len(pairs) > 0.9 * len(watch.sim)
    np.testing.assert_allclose([d for _, d in pairs], [lc for lc, _ in pairs], atol=TRUNK_MATCH_M)


JOYSTICK_POLICY = ROOT / "policies" / "joystick" / "joystick.safetensors"
STAND_S = 5.0                   # the joystick policy holds the robot up this long, zero command


@pytest.mark.slow
def test_over_dds_a_walking_policy_keeps_the_robot_standing(netns):
    """What a PD hold with the policy's own soft gains cannot do in this model (it tips over at ~1.3 s), the
    shipped joystick expert does over DDS: standing start, the short PREPARE of the walk evaluation, then
    STAND_S with a zero command (no joystick is sent: the runtime zeroes a stale one), trunk up all the way,
    no fault."""
    from sim_hil.eval.plans import STANDING_PREPARE_S
    watch = LcmWatch()
    runtime = start_runtime(JOYSTICK_POLICY, "--transport", "dds", "--clock", "lockstep", "--autostart",
                            "--prepare-s", str(STANDING_PREPARE_S))
    sim = start_sim("--dds", "--clock", "lockstep", "--spawn", "standing", "--status-rate", "50",
                    "--duration", str(STANDING_PREPARE_S + STAND_S))
    watch.pump_while(lambda: sim.poll() is None, 300)
    assert sim.poll() == 0, f"sim failed: {sim.communicate()[1][-2000:] if sim.poll() is not None else 'timeout'}"
    code, err = stop(runtime)
    assert code == 0, f"runtime exit {code}: {err}"
    assert watch.status[-1].mode_name == "POLICY" and watch.status[-1].policy_ticks > 0
    assert all(s.fault_bits & LATCHED_FAULT_MASK == 0 for s in watch.status), watch.status[-1].last_fault
    assert watch.sim[-1].utime * 1e-6 >= STANDING_PREPARE_S + STAND_S - 0.1, "the run ended early"
    assert min(s.trunk_height for s in watch.sim) > STANDING_TRUNK_MIN_M, "the robot went down"


@pytest.mark.slow
def test_realtime_over_dds_the_runtime_sees_the_robot_and_commands_it(netns):
    watch = LcmWatch()
    listener = DdsRobotPeer(write_state=False)
    sim = start_sim("--dds", "--clock", "realtime", "--spawn", "standing", "--duration", "10")
    # the runtime's 3 s start once the sim is live (its LCM status), however long a loaded machine takes to start it
    deadline = time.monotonic() + LIVENESS_S
    while not watch.sim and sim.poll() is None and time.monotonic() < deadline:
        watch.lc.handle_timeout(20)
    assert watch.sim, "the sim never came up"
    runtime = start_runtime(UNTRAINED_STUDENT, "--transport", "dds", "--clock", "realtime", "--autostart",
                            "--duration", "3")
    watch.pump_while(lambda: runtime.poll() is None, LIVENESS_S)
    code, err = stop(runtime)
    stop(sim)
    listener.take()
    assert code == 0, err
    # The mode ladder only leaves PASSIVE on live state: the runtime read rt/low_state.
    assert any(s.mode_name != "PASSIVE" for s in watch.status), [s.mode_name for s in watch.status]
    assert listener.cmds, "no LowCmd_ on rt/joint_ctrl"
    assert all(c.cmd_type.value == contract.DDS["cmd_type_serial"] and len(c.motor_cmd) == N for c in listener.cmds)
    assert all(m.weight == contract.DDS["motor_weight"] for m in listener.cmds[-1].motor_cmd)


# ------------------------------------------------------------------------------------ a fake robot
@pytest.fixture
def dds_runtime(netns):
    started = []

    def start(*args: str):
        peer = DdsRobotPeer()
        proc = start_runtime(UNTRAINED_STUDENT, "--transport", "dds", "--clock", "realtime", *args)
        started.append(proc)
        return peer, proc

    yield start
    for proc in started:
        stop(proc)


def _echoed_q(cmd) -> np.ndarray:
    return np.array([m.q for m in cmd.motor_cmd])


def _until_echo(peer: DdsRobotPeer, sample, q) -> None:
    """PASSIVE echoes the live q as the target every tick: write until the echo shows q."""
    deadline = time.monotonic() + LIVENESS_S
    while time.monotonic() < deadline:
        peer.write(sample)
        if any(np.allclose(_echoed_q(c), q, atol=1e-5) for c in peer.take()):
            return
        time.sleep(0.01)
    raise AssertionError("the runtime never echoed the written state")


def test_malformed_and_oversized_low_states_are_rejected_with_the_state_unchanged(dds_runtime, netns):
    peer, proc = dds_runtime()
    watch = LcmWatch()
    q0 = np.asarray(read_artifact(UNTRAINED_STUDENT)[3]["default_pose"], np.float64)
    _until_echo(peer, low_state(q0), q0)
    bad_q = q0 + 0.3
    nan_q = q0.copy()
    nan_q[11] = float("nan")
    malformed = [low_state(bad_q, n_motors=N + 1), low_state(bad_q, n_motors=200), low_state(bad_q, n_motors=N - 1),
                 low_state(bad_q, n_motors=0), low_state(nan_q), low_state(bad_q, rpy=(0.0, float("nan"), 0.0))]
    for sample in malformed:
        peer.write(sample)
        time.sleep(0.02)
    peer.take()
    peer.cmds.clear()
    time.sleep(0.1)
    after = peer.take()
    assert after, "the runtime stopped commanding"
    for c in after:                       # every target still the last good state's q
        np.testing.assert_allclose(_echoed_q(c), q0, atol=1e-5)
    n = len(watch.status)
    watch.pump_while(lambda: len(watch.status) < n + 2, LIVENESS_S)
    status = watch.status[-1]
    assert status.decode_errors == len(malformed), status.decode_errors
    assert "LowState_ rejected" in status.info, status.info
    q1 = q0 - 0.1                         # and a good sample is still taken
    _until_echo(peer, low_state(q1), q1)


def test_fault_and_exit_both_leave_the_robot_damped(dds_runtime, netns):
    peer, proc = dds_runtime("--autostart", "--prepare-s", "0.02")
    watch = LcmWatch()
    q0 = np.asarray(read_artifact(UNTRAINED_STUDENT)[3]["default_pose"], np.float64)
    deadline = time.monotonic() + LIVENESS_S
    while time.monotonic() < deadline and not any(s.mode == MODE["FAULT"] for s in watch.status):
        if time.monotonic() < deadline - LIVENESS_S / 2:
            peer.write(low_state(q0))     # half the time a live robot; then the state stops: stale, FAULT
        watch.lc.handle_timeout(2)
        peer.take()
    assert any(s.mode == MODE["FAULT"] for s in watch.status), [s.mode_name for s in watch.status][-5:]
    peer.cmds.clear()
    time.sleep(0.05)
    fault_cmds = peer.take()
    assert fault_cmds and all(m.kp == 0.0 and m.kd > 0.0 for c in fault_cmds for m in c.motor_cmd)
    code, err = stop(proc)
    assert code == 0, err
    time.sleep(0.05)
    peer.take()
    last = peer.cmds[-1]
    assert all(m.kp == 0.0 and m.kd > 0.0 for m in last.motor_cmd), "exit did not send a damping LowCmd_"


def test_estop_over_lcm_damps_the_dds_robot_within_a_tick(dds_runtime, netns):
    """The operator channels stay on LCM: an e-stop there turns the very next LowCmd_ into damping."""
    from t1 import runtime_cmd_t
    peer, proc = dds_runtime("--autostart", "--prepare-s", "0.02")
    watch = LcmWatch()
    q0 = np.asarray(read_artifact(UNTRAINED_STUDENT)[3]["default_pose"], np.float64)
    deadline = time.monotonic() + LIVENESS_S
    while time.monotonic() < deadline and not any(c.motor_cmd[0].kp > 0 for c in peer.take()):
        peer.write(low_state(q0))          # live robot: the ladder reaches PREPARE (kp > 0)
        time.sleep(0.002)
    estop = runtime_cmd_t()
    estop.verb = "estop"
    watch.lc.publish(contract.CH_RUNTIME_CMD, estop.encode())    # unsigned: estop is obeyed from anyone
    damped = False
    while time.monotonic() < deadline and not damped:
        peer.write(low_state(q0))
        damped = any(all(m.kp == 0.0 and m.kd > 0.0 for m in c.motor_cmd) for c in peer.take())
        time.sleep(0.002)
    assert damped, "no damping LowCmd_ after the e-stop"
    n = len(watch.status)
    while time.monotonic() < deadline and len(watch.status) < n + 2:   # the robot stays live meanwhile
        peer.write(low_state(q0))
        watch.lc.handle_timeout(2)
    assert watch.status[-1].mode_name == "DAMPING", (watch.status[-1].mode_name, watch.status[-1].last_fault)


def test_the_sim_refuses_unusable_low_cmds_naming_the_problem():
    from messages import dds_types
    from sim_hil.dds_bridge import validate_low_cmd

    def cmd(n=N, cmd_type=dds_types.CmdType.SERIAL, **field):
        m = dict(mode=0, q=0.0, dq=0.0, tau=0.0, kp=10.0, kd=1.0, weight=0.0)
        motors = [dds_types.MotorCmd(**m) for _ in range(n)]
        for name, value in field.items():
            setattr(motors[3], name, value)
        return dds_types.LowCmd(cmd_type=cmd_type, motor_cmd=motors)

    assert validate_low_cmd(cmd()) is None
    assert "not SERIAL" in validate_low_cmd(cmd(cmd_type=dds_types.CmdType.PARALLEL))
    assert "24 entries" in validate_low_cmd(cmd(n=N + 1))
    assert "q contains NaN" in validate_low_cmd(cmd(q=float("nan")))
    assert "kp outside" in validate_low_cmd(cmd(kp=-1.0))

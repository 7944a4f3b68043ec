"""The runtime believes only its robot, tried as an outside program would: sim_hil (standing) and
t1-runtime (the student in POLICY) started as the launcher starts them, with the run's robot key, while a
second program publishes state on the live group: lcm-logplayer replaying the run's own recorded frames, a
second sim_hil (another run's key), a forged stream 100 000 ahead of the robot's with a 70 degree pitch, a
second rt/low_state writer on DDS. In each the robot is never commanded from the forged state (the runtime
stays in POLICY on the robot's frames, the robot stands), the status names the cause, and the run's own log
keeps every frame of the robot (sequence numbers without a hole). Without a robot key (a bench) the forged
stream is a FAULT named "second state source" (rule R12). Every wait has a timeout; none is a fixed sleep."""
from __future__ import annotations

import math
import subprocess
import time
from pathlib import Path

import lcm
import numpy as np
import pytest
from t1 import controller_status_t, imu_t, joint_state_t, sim_status_t

from common.artifact import read_artifact
from common.events import FALLEN_TRUNK_HEIGHT_M
from messages import auth, contract
from sim_hil.launch import ROOT, start_runtime, start_sim, stop
from sim_hil.lcmlog.capture import LogCapture, RunInfo, lcm_tool
from sim_hil.lcmlog.eventlog import LogProblems, open_log, read_events, write_events

STUDENT = ROOT / "policies" / "student" / "student.safetensors"
HOME_Q = read_artifact(STUDENT)[3]["default_pose"]
STATE_REFUSED_BIT = 1 << 25       # runtime/include/t1rt/safety.hpp fault_bit::kStateRefused
FORGED_PITCH_RAD = math.radians(70.0)
FORGED_RATE_HZ = 500.0
ATTACK_S = 2.0                    # how long the second source publishes
SETTLE_S = 1.0                    # POLICY before and after the attack
LIVENESS_S = 120.0                # bound on a start or a wait (not a timing check)
SEQ_AHEAD = 100_000
MAX_TILT_RAD = math.radians(30.0)  # a standing robot's trunk tilts far less; the forged pitch is 70 degrees


class Watch:
    """What an operator sees on the group: the runtime's status, the sim's truth, the robot's newest seq."""

    def __init__(self, url: str):
        self.lc = lcm.LCM(url)
        self.status: controller_status_t | None = None
        self.sim: sim_status_t | None = None
        self.seq = -1                                  # the newest imu_t seq on the group
        self.statuses: list[controller_status_t] = []
        self.min_trunk_m = math.inf
        self.lc.subscribe(contract.CH_CONTROLLER_STATUS, self._on_status)
        self.lc.subscribe(contract.CH_SIM_STATUS, self._on_sim)
        self.lc.subscribe(contract.CH_IMU, lambda _c, d: self._on_imu(imu_t.decode(d), d))
        self.watching_trunk = False
        self.robot: auth.Sender | None = None          # set: the tilt of the robot's own frames is watched
        self.max_tilt_rad = 0.0

    def _on_status(self, _c, data):
        self.status = controller_status_t.decode(data)
        self.statuses.append(self.status)

    def _on_sim(self, _c, data):
        self.sim = sim_status_t.decode(data)
        if self.watching_trunk:
            self.min_trunk_m = min(self.min_trunk_m, self.sim.trunk_height)

    def _on_imu(self, m, data: bytes):
        self.seq = max(self.seq, m.seq)
        if self.watching_trunk and self.robot and m.tag_size and \
                auth.tag(self.robot.key, contract.CH_IMU, auth.signed_body(data)) == bytes(m.tag):
            w, x, y, z = m.quat                        # the body z axis against the world's
            self.max_tilt_rad = max(self.max_tilt_rad, math.acos(max(-1.0, min(1.0, 1 - 2 * (x * x + y * y)))))

    def pump(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.lc.handle_timeout(10)

    def until(self, predicate, what: str, procs=()) -> None:
        deadline = time.monotonic() + LIVENESS_S
        while not predicate():
            for p in procs:
                assert p.poll() is None, f"{what}: a process exited {p.returncode}: {p.communicate()[1][-1500:]}"
            assert time.monotonic() < deadline, f"{what}: not within {LIVENESS_S} s"
            self.lc.handle_timeout(20)


class Run:
    """sim_hil and t1-runtime of one run with the run's keys, its own LCM log, a watch on the group."""

    def __init__(self, tmp: Path, url: str, robot_key: bool = True, dds: bool = False):
        self.url, self.dds = url, dds
        self.run_key = auth.RunKey() if robot_key else None
        self.robot = auth.read_key_file(self.run_key.robot_key_path)[0] if robot_key else None   # stop() removes it
        self.log = tmp / "run.lcmlog"
        self.capture = LogCapture(self.log, url, RunInfo(run_name="state_source", producer="test", clock="realtime"))
        self.watch = Watch(url)
        self.watch.robot = self.robot
        # over LCM in lockstep: each tick answers the robot's own state, so a loaded host (make test -n 2 on 2
        # cores, SCHED_FIFO refused) cannot starve the loop past the motors' 50 ms watchdog (a fault no forged
        # state caused); what is tried is which state the runtime believes, and the attack still runs on the
        # wall clock beside it. Over DDS realtime (its lockstep waits on the state topic the forger writes to)
        clock = ["--clock", "realtime" if dds else "lockstep"]
        sim_args = [*clock, "--spawn", "standing", "--lcm-url", url] + (["--dds"] if dds else [])
        self.sim = start_sim(*sim_args, run_key=self.run_key)
        if dds:    # (a lockstep sim reports once the runtime answers it)
            self.watch.until(lambda: self.watch.sim is not None, "the sim's first status", [self.sim])
        link = ["--transport", "dds"] if dds else []
        self.runtime = start_runtime(STUDENT, *clock, "--autostart", "--prepare-s", "1", "--lcm-url", url, *link,
                                     run_key=self.run_key)
        self.watch.until(lambda: self.watch.status is not None and self.watch.status.mode_name == "POLICY",
                         "the runtime in POLICY", [self.sim, self.runtime])
        self.watch.pump(SETTLE_S)
        self.watch.watching_trunk = True
        self.attack_from = len(self.watch.statuses)

    def stop(self) -> str:
        code, err = stop(self.runtime)
        stop(self.sim)
        self.capture.stop()
        assert code == 0, err[-2000:]
        return err

    def during_attack(self) -> list[controller_status_t]:
        return self.watch.statuses[self.attack_from:]

    def robot_frames_kept(self) -> None:
        """Every imu_t / joint_state_t the robot signed is in the run's log: its seq numbers have no hole."""
        log = open_log(self.log)
        robot = self.robot
        for channel in (contract.CH_IMU, contract.CH_JOINT_STATE):
            seqs = sorted({m.seq for ev, m in log.messages[channel]
                           if m.tag_size and auth.tag(robot.key, channel, auth.signed_body(ev.data)) == bytes(m.tag)})
            assert seqs and seqs == list(range(seqs[0], seqs[-1] + 1)), \
                f"{channel}: {seqs[-1] - seqs[0] + 1 - len(seqs)} of the robot's frames missing from the log"


def _forged_state(seq: int) -> tuple[imu_t, joint_state_t]:
    imu, js = imu_t(), joint_state_t()
    imu.utime = js.utime = int(time.monotonic() * 1e6)
    imu.seq = js.seq = seq
    imu.quat = [math.cos(FORGED_PITCH_RAD / 2), 0.0, math.sin(FORGED_PITCH_RAD / 2), 0.0]
    imu.accel = [0.0, 0.0, 9.81]
    js.q = list(HOME_Q)
    return imu, js


def _publish_forged(watch: Watch, first_seq: int, signer=None) -> int:
    """The forger: imu_t and joint_state_t numbered from first_seq at FORGED_RATE_HZ for ATTACK_S; returns the
    frames sent."""
    start, sent = time.monotonic(), 0
    while (t := time.monotonic() - start) < ATTACK_S:
        for channel, msg in zip((contract.CH_IMU, contract.CH_JOINT_STATE), _forged_state(first_seq + sent)):
            watch.lc.publish(channel, signer.sign(channel, msg) if signer else msg.encode())
        sent += 1
        watch.lc.handle_timeout(max(0, int((sent / FORGED_RATE_HZ - t) * 1000)))   # paces, and keeps watching
    return sent


def _robot_stood_on_its_own_state(run: Run) -> controller_status_t:
    run.watch.pump(SETTLE_S)
    status = run.watch.status
    modes = {s.mode_name for s in run.during_attack()}
    assert modes == {"POLICY"}, f"modes {modes}, last fault: {status.last_fault}"
    if run.dds:                                        # one simulator: its truth is the robot's
        assert run.watch.min_trunk_m > FALLEN_TRUNK_HEIGHT_M, f"the robot fell: trunk {run.watch.min_trunk_m:.2f} m"
    else:                                              # the robot's own signed IMU frames
        assert 0 < run.watch.max_tilt_rad < MAX_TILT_RAD, \
            f"the robot tilted {math.degrees(run.watch.max_tilt_rad):.0f} deg"
    warned = [s for s in run.during_attack() if s.fault_bits & STATE_REFUSED_BIT]
    assert warned, "no status warned of the refused state"
    return status


@pytest.fixture
def run(netns, tmp_path):
    runs = []

    def start(**kwargs) -> Run:
        runs.append(Run(tmp_path, netns, **kwargs))
        return runs[-1]

    yield start
    for r in runs:
        if r.runtime.poll() is None or r.sim.poll() is None:
            stop(r.runtime)
            stop(r.sim)
            r.capture.stop()


@pytest.mark.slow
def test_lcm_logplayer_replaying_the_recorded_run_on_the_live_group_is_refused(run, tmp_path):
    r = run()
    so_far = read_events(r.log, LogProblems())         # the run's own frames, signed by its robot, seconds old
    state = [ev for ev in so_far if ev.channel in (contract.CH_IMU, contract.CH_JOINT_STATE)]
    assert len(state) > 100, "the run's log holds no state yet"
    recorded = write_events(tmp_path / "recorded.lcmlog", state)
    player = subprocess.Popen([lcm_tool("lcm-logplayer"), f"--lcm-url={r.url}", str(recorded)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    r.watch.until(lambda: player.poll() is not None, "lcm-logplayer to finish")
    assert player.returncode == 0, player.stderr.read()
    status = _robot_stood_on_its_own_state(r)
    assert status.state_refused_replayed + status.state_refused_stale >= len(state) // 2, status.state_source
    r.stop()
    r.robot_frames_kept()


@pytest.mark.slow
def test_a_second_sim_hil_on_the_group_is_refused(run):
    r = run()
    other = auth.RunKey()                              # another launcher's run: its own robot key
    second = start_sim("--clock", "realtime", "--spawn", "fallen:3", "--lcm-url", r.url, "--duration",
                       str(ATTACK_S), run_key=other)
    try:
        r.watch.until(lambda: second.poll() is not None, "the second sim to finish its run")
    finally:
        stop(second)
        other.close()
    assert second.returncode == 0
    status = _robot_stood_on_its_own_state(r)
    assert status.state_refused_bad_tag > 0, status.state_source
    r.stop()
    r.robot_frames_kept()


@pytest.mark.slow
def test_a_forged_stream_ahead_of_the_robots_is_refused(run):
    r = run()
    robot_seq = r.watch.seq
    sent = _publish_forged(r.watch, robot_seq + SEQ_AHEAD)
    status = _robot_stood_on_its_own_state(r)
    assert status.state_refused_unsigned >= sent, (status.state_refused_unsigned, sent)
    assert "unsigned" in status.state_source or "refused" in status.state_source, status.state_source
    r.stop()
    r.robot_frames_kept()


@pytest.mark.slow
def test_without_a_robot_key_a_forged_stream_is_a_fault_named_second_state_source(run):
    r = run(robot_key=False)
    _publish_forged(r.watch, r.watch.seq + SEQ_AHEAD)
    r.watch.until(lambda: r.watch.status.mode_name == "FAULT", "the FAULT")
    assert "second state source on T1_" in r.watch.status.last_fault, r.watch.status.last_fault
    assert "second state source" in r.watch.status.state_source, r.watch.status.state_source
    r.stop()


@pytest.mark.slow
def test_a_second_dds_writer_is_refused_and_named_by_its_guid(run):
    from tests.dds_peer import DdsRobotPeer, low_state
    r = run(dds=True)
    forger = DdsRobotPeer(read_commands=False)
    start, sent = time.monotonic(), 0
    while (t := time.monotonic() - start) < ATTACK_S:
        forger.write(low_state(np.asarray(HOME_Q), rpy=(0.0, FORGED_PITCH_RAD, 0.0)))
        sent += 1
        r.watch.lc.handle_timeout(max(0, int((sent / FORGED_RATE_HZ - t) * 1000)))
    status = _robot_stood_on_its_own_state(r)
    assert "second writer" in status.info, status.info
    guid = status.info.split("second writer ", 1)[1].split()[0]
    assert len(guid) == 32 and int(guid, 16) >= 0, guid
    r.stop()

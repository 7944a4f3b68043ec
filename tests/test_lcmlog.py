"""LCM logs (sim_hil/lcmlog): the reader survives damaged logs and says what is wrong; the plot; and, in
the namespace, a lockstep trial's log replayed through the C++ runtime reproduces the logged command
stream exactly with the logged policy and shows where another policy diverges."""
from __future__ import annotations

import json
import subprocess
import sys
import time

import numpy as np
import pytest
from t1 import imu_t, joint_command_t, joint_state_t

from common.artifact import read_artifact, write_artifact
from messages import contract
from sim_hil.launch import ROOT, _env
from sim_hil.lcmlog.eventlog import Event, LogProblems, open_log, read_events, write_events
from sim_hil.lcmlog.plot import parse_joints, plot_log

STUDENT = ROOT / "policies" / "student_untrained" / "student_untrained.safetensors"
N = contract.NUM_JOINTS
TICK_US = 2000


def _state(seq: int) -> bytes:
    m = joint_state_t()
    m.utime, m.seq = seq * TICK_US, seq
    m.q, m.dq, m.tau_est = [0.1 * seq] * N, [0.0] * N, [0.0] * N
    m.motor_status = [0] * N
    return m.encode()


def _command(seq: int) -> bytes:
    m = joint_command_t()
    m.utime, m.seq, m.state_seq, m.mode = seq * TICK_US, seq, seq, 3
    m.q_des, m.dq_des, m.kp, m.kd, m.tau_ff = [0.1 * seq] * N, [0.0] * N, [50.0] * N, [1.0] * N, [0.0] * N
    return m.encode()


def _events(ticks: int = 10) -> list[Event]:
    out = []
    for k in range(ticks):
        out.append(Event(0, k * TICK_US, contract.CH_JOINT_STATE, _state(k)))
        out.append(Event(0, k * TICK_US + 100, contract.CH_JOINT_CMD, _command(k)))
    return out


def test_clean_log_round_trip(tmp_path):
    path = write_events(tmp_path / "clean.lcmlog", _events())
    log = open_log(path)
    assert log.problems.messages(path) == []
    assert len(log.messages[contract.CH_JOINT_STATE]) == 10 and len(log.messages[contract.CH_JOINT_CMD]) == 10
    assert log.messages[contract.CH_JOINT_STATE][3][1].seq == 3


def test_comparison_is_identical_only_when_no_command_is_missing(tmp_path):
    """Equal commands where both streams have one are not enough: a state the replay left unanswered, or a
    logged command the replay lacks, makes the streams different (and the report says so)."""
    from sim_hil.lcmlog.replay import compare
    log = open_log(write_events(tmp_path / "l.lcmlog", _events()))
    replayed = {cmd.state_seq: cmd for _ev, cmd in log.messages[contract.CH_JOINT_CMD]}
    whole = compare(log, replayed, "p", "p", "lockstep")
    assert whole.identical and whole.compared_ticks == 10
    del replayed[7]
    partial = compare(log, replayed, "p", "p", "lockstep")
    assert not partial.identical and partial.only_in_log == 1 and partial.first_diverging_state_seq is None
    assert "DIFFERENT" in partial.text()


def test_truncated_log_keeps_every_whole_event(tmp_path):
    path = write_events(tmp_path / "t.lcmlog", _events())
    path.write_bytes(path.read_bytes()[:-50])            # the last command loses its tail
    log = open_log(path)
    assert len(log.messages[contract.CH_JOINT_STATE]) == 10 and len(log.messages[contract.CH_JOINT_CMD]) == 9
    assert any("truncated" in m for m in log.problems.messages(path))


def test_corrupt_bytes_are_skipped_and_reading_resumes(tmp_path):
    blob = write_events(tmp_path / "c.lcmlog", _events()).read_bytes()
    events = read_events(tmp_path / "c.lcmlog", LogProblems())
    hit = events[5].offset                               # overwrite event 5's header and part of its body
    damaged = blob[:hit] + b"\x00" * 40 + blob[hit + 40:]
    (tmp_path / "c.lcmlog").write_bytes(damaged)
    log = open_log(tmp_path / "c.lcmlog")
    assert len(log.events) == 19
    msgs = log.problems.messages(log.path)
    assert len(msgs) == 1 and f"corrupt bytes {hit}.." in msgs[0]


def test_unknown_channel_and_other_type_version_are_named(tmp_path):
    events = _events(3)
    wrong = bytearray(_state(7))
    wrong[:8] = (0x1234).to_bytes(8, "big")             # a joint_state_t of another version
    events += [Event(0, 9_000, "SOMEONE_ELSES", b"\x01\x02"), Event(0, 9_100, contract.CH_JOINT_STATE, bytes(wrong)),
               Event(0, 9_200, contract.CH_IMU, imu_t().encode()[:12])]      # cut short
    log = open_log(write_events(tmp_path / "u.lcmlog", events))
    text = "\n".join(log.problems.messages(log.path))
    assert "'SOMEONE_ELSES' is not in messages/contract.json: 1 events skipped" in text
    assert "T1_JOINT_STATE: 1 events of another joint_state_t version (fingerprint 0x0000000000001234" in text
    assert "T1_IMU: 1 events do not decode as imu_t" in text
    assert len(log.messages[contract.CH_JOINT_STATE]) == 3        # what could be read still is


def test_not_a_log_is_refused_clearly(tmp_path):
    (tmp_path / "x.lcmlog").write_bytes(b"this is not an lcm log at all")
    with pytest.raises(ValueError, match="no readable LCM event"):
        open_log(tmp_path / "x.lcmlog")
    run = subprocess.run([sys.executable, "-m", "sim_hil.lcmlog", "info", str(tmp_path / "x.lcmlog")],
                         cwd=ROOT, env=_env(), capture_output=True, text=True)
    assert run.returncode == 2 and "no readable LCM event" in run.stderr


def test_plot_of_a_damaged_log(tmp_path):
    path = write_events(tmp_path / "p.lcmlog", _events(50))
    path.write_bytes(path.read_bytes()[:-10])
    run = subprocess.run([sys.executable, "-m", "sim_hil.lcmlog", "plot", str(path), "--joints", "Waist"],
                         cwd=ROOT, env=_env(), capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "truncated" in run.stderr and path.with_suffix(".png").stat().st_size > 0
    assert plot_log(open_log(path), tmp_path / "q.png").is_file()
    with pytest.raises(ValueError, match="not in messages/contract.json"):
        parse_joints("Left_Knee,Waist")


def _other_student(path):
    """The untrained student with its output bias shifted: a different policy on the same inputs."""
    layers, mean, std, manifest = read_artifact(STUDENT)
    layers = [(np.asarray(w), np.asarray(b)) for w, b in layers]
    layers[-1] = (layers[-1][0], layers[-1][1] + 0.2)
    write_artifact(path, layers, mean, std, {k: v for k, v in manifest.items() if k != "content_hash"})
    return path


@pytest.mark.slow
def test_lockstep_log_replays_exactly_and_another_policy_diverges(tmp_path, netns):
    out = tmp_path / "eval"
    run = subprocess.run([sys.executable, "-m", "sim_hil.eval", "getup", "--policy", str(STUDENT), "--trials", "1",
                          "--seconds", "2.6", "--jobs", "1", "--no-video", "--out", str(out)],
                         cwd=ROOT, env=_env(), capture_output=True, text=True, timeout=150)
    assert run.returncode == 0, run.stderr[-3000:]
    (log_path,) = sorted((out / "logs").glob("*.lcmlog"))
    log = open_log(log_path)
    assert log.problems.messages(log_path) == []                  # lcm-logger left a whole file
    info = log.first(contract.CH_RUN_INFO)
    assert info.policy_path == str(STUDENT) and "--autostart" in info.runtime_args
    states = log.messages[contract.CH_JOINT_STATE]
    assert [m.seq for _, m in states] == list(range(1300))        # 2.6 s at 500 Hz, not one missed

    def replay(*policy):
        return subprocess.run([sys.executable, "-m", "sim_hil.lcmlog", "replay", str(log_path), *policy,
                               "--out", str(tmp_path / "r")], cwd=ROOT, env=_env(), capture_output=True,
                              text=True, timeout=120)

    same = replay()
    assert same.returncode == 0, same.stdout + same.stderr
    report = json.loads((tmp_path / "r.replay.json").read_text())
    assert report["identical"] and report["compared_ticks"] == 1300 and report["unanswered_states"] == 0

    other = replay("--policy", str(_other_student(tmp_path / "other.safetensors")))
    assert other.returncode == 1, other.stdout + other.stderr
    report = json.loads((tmp_path / "r.replay.json").read_text())
    logged = {m.state_seq: m for _, m in log.messages[contract.CH_JOINT_CMD]}
    first = report["first_diverging_state_seq"]
    # PREPARE does not use the policy: the commands agree until the first POLICY tick, then differ
    assert logged[first].mode == joint_command_t.MODE_POLICY and logged[first - 1].mode != joint_command_t.MODE_POLICY
    assert max(report["max_abs_dq_des_rad"].values()) > 0


def test_spy_plays_a_damaged_log_headless_and_cleans_up(tmp_path, netns):
    path = write_events(tmp_path / "s.lcmlog", _events(100))
    path.write_bytes(path.read_bytes()[:-10])            # lcm-logplayer alone would stop at the damage
    env = {k: v for k, v in _env().items() if k != "DISPLAY"}
    run = subprocess.run([sys.executable, "-m", "sim_hil.lcmlog", "spy", str(path), "--speed", "4"], cwd=ROOT,
                         env=env, capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "headless, xvfb" in run.stdout and "truncated" in run.stderr
    left = subprocess.run(["pgrep", "-f", "lcm.spy.Spy"], capture_output=True, text=True).stdout.split()
    assert not left, f"lcm-spy left running: {left}"


def test_a_logging_sim_stopped_by_sigterm_ends_its_log_and_its_logger(tmp_path, netns):
    """launch.stop() ends the sim with SIGTERM: the sim stops its lcm-logger and the log is whole, with the
    run_info_t end marker after the run's states."""
    from sim_hil.launch import start_sim, stop
    path = tmp_path / "term.lcmlog"
    sim = start_sim("--clock", "realtime", "--spawn", "standing", "--log", str(path))
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and sim.poll() is None and not (path.exists() and path.stat().st_size > 50_000):
        time.sleep(0.2)                                  # the logger is up and the sim is publishing
    code, err = stop(sim)
    assert code == 0, err[-2000:]
    left = subprocess.run(["pgrep", "-f", f"lcm-logger.*{path}"], capture_output=True, text=True).stdout.split()
    assert not left, f"lcm-logger left running: {left}"
    log = open_log(path)
    assert log.problems.messages(path) == []
    states = log.messages[contract.CH_JOINT_STATE]
    markers = [ev.offset for ev, _ in log.messages[contract.CH_RUN_INFO]]
    assert states and len(markers) >= 2 and markers[-1] > states[-1][0].offset


def test_make_sim_logs_by_default_under_out_sim_and_not_with_no_log(netns):
    """`python -m sim_hil` (make sim) names its log after the run in out/sim; --no-log writes none."""
    from sim_hil import config
    before = set(config.SIM_LOG_DIR.glob("*.lcmlog")) if config.SIM_LOG_DIR.exists() else set()
    for extra in (["--no-log"], []):
        run = subprocess.run([sys.executable, "-m", "sim_hil", "--quiet", "--scenario", "flat", "--spawn", "standing",
                              "--duration", "0.3", *extra], cwd=ROOT, env=_env(), capture_output=True, text=True,
                             timeout=120)
        assert run.returncode == 0, run.stderr[-2000:]
        new = set(config.SIM_LOG_DIR.glob("*.lcmlog")) - before if config.SIM_LOG_DIR.exists() else set()
        if extra:
            assert not new, f"--no-log wrote {new}"
    (path,) = new
    try:
        assert path.name.startswith("flat_standing_realtime_")
        log = open_log(path)
        assert log.problems.messages(path) == [] and log.messages[contract.CH_JOINT_STATE]
        assert log.first(contract.CH_RUN_INFO).producer == "sim"
    finally:
        path.unlink()


def test_the_logger_refuses_bad_arguments_and_skips_foreign_channels(tmp_path, netns):
    """t1-lcm-logger (sim_hil/core/lcm_logger.cpp): a wrong argument exits 2 naming it; it logs only the
    channels it is given, whole, in order, and writes what it holds at SIGINT."""
    import signal

    import lcm

    from sim_hil.launch import LOGGER
    for bad, why in ((["--bogus"], "--bogus"), (["--flush-interval=0", "--lcm-url=x", "--channels=A", "f"], "ms > 0"),
                     (["--lcm-url", contract.lcm_url(), str(tmp_path / "x.lcmlog")], "required")):
        run = subprocess.run([str(LOGGER), *bad], capture_output=True, text=True)
        assert run.returncode == 2 and why in run.stderr, run.stderr
    path = tmp_path / "kept.lcmlog"
    proc = subprocess.Popen([str(LOGGER), f"--lcm-url={contract.lcm_url()}", f"--channels={contract.CH_JOINT_STATE}",
                             "--flush-interval=10", str(path)], stderr=subprocess.PIPE, text=True)
    lc = lcm.LCM(contract.lcm_url())
    deadline = time.monotonic() + 10
    while not (path.exists() and path.stat().st_size > 0) and time.monotonic() < deadline:
        lc.publish(contract.CH_JOINT_STATE, _state(0))    # until the logger is listening
        time.sleep(0.02)
    for seq in range(1, 2001):
        lc.publish(contract.CH_JOINT_STATE, _state(seq))
        lc.publish("NOT_OURS", b"x")
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=10) == 0, proc.stderr.read()
    seqs = [joint_state_t.decode(e.data).seq for e in read_events(path, LogProblems())]
    assert seqs[-2000:] == list(range(1, 2001))          # every one, in order; nothing else


def test_state_recorded_before_state_was_signed_is_kept_as_unsigned_frames_and_named(tmp_path):
    """A log from before imu_t / joint_state_t carried the robot's signature: its state events decode as
    today's types, unsigned, every field kept, and the reader names the old version by its fingerprint."""
    from messages.auth import LEGACY_STATE_FINGERPRINTS
    unsigned_tail = 8 + 8 + 2                           # sender_id, timestamp_us, tag_size: what the old type lacked
    imu = imu_t()
    imu.seq, imu.quat, imu.accel = 5, [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 9.81]
    old_imu = LEGACY_STATE_FINGERPRINTS["imu_t"].to_bytes(8, "big") + imu.encode()[8:-unsigned_tail]
    old_js = LEGACY_STATE_FINGERPRINTS["joint_state_t"].to_bytes(8, "big") + _state(6)[8:-unsigned_tail]
    log = open_log(write_events(tmp_path / "old.lcmlog", [Event(0, 1, contract.CH_IMU, old_imu),
                                                          Event(0, 2, contract.CH_JOINT_STATE, old_js)]))
    got_imu, got_js = log.first(contract.CH_IMU), log.first(contract.CH_JOINT_STATE)
    assert (got_imu.seq, list(got_imu.accel), got_imu.sender_id, got_imu.tag_size) == \
        (5, [0.0, 0.0, np.float32(9.81)], 0, 0)
    assert got_js.encode() == _state(6) and not log.problems.wrong_version
    text = "\n".join(log.problems.messages(log.path))
    assert ("1 events of the imu_t version before state was signed "
            f"(fingerprint {LEGACY_STATE_FINGERPRINTS['imu_t']:#018x})") in text

"""Waits say what they wait for, once and then at a slow period: a lockstep sim without a controller names the
command it waits for and where, a runtime without state names the state it lacks and where."""
from __future__ import annotations

import io
import queue
import subprocess
import threading
import time

from sim_hil import config
from sim_hil.launch import ROOT, start_runtime, start_sim
from sim_hil.wait_notice import WaitNotice

UNTRAINED = ROOT / "policies" / "student_untrained" / "student_untrained.safetensors"
STARTUP_S = 60.0            # a process start on a loaded 2-core machine
RUNTIME_REPEAT_S = 10.0     # runtime/src/controller.cpp kNoStateRepeatNs
PERIOD_SLACK_S = 1.0        # a notice is never early; this much early still counts as on time (thread wake-ups)


def _lines(proc) -> queue.Queue:
    """stderr lines of proc as they come (a reader thread: the test waits on the queue with a deadline)."""
    q: queue.Queue = queue.Queue()

    def read():
        for line in proc.stderr:
            q.put((time.monotonic(), line.rstrip("\n")))
    threading.Thread(target=read, daemon=True).start()
    return q


def _end(proc, timeout_s: float = 10.0) -> None:
    """SIGTERM, then SIGKILL (a lockstep sim may sit in one C call of its first-command wait); its reader thread
    owns stderr, so no communicate() here."""
    proc.terminate()
    try:
        proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
    if getattr(proc, "run_key", None) is not None:
        proc.run_key.close()


def _next(q: queue.Queue, text: str, timeout_s: float) -> tuple[float, str]:
    deadline = time.monotonic() + timeout_s
    while (left := deadline - time.monotonic()) > 0:
        try:
            at, line = q.get(timeout=left)
        except queue.Empty:
            break
        if text in line:
            return at, line
    raise AssertionError(f"no line with {text!r} within {timeout_s} s")


def test_the_notice_comes_once_then_at_its_period_while_the_wait_lasts():
    out, checks = io.StringIO(), iter([True, True, False])
    notice = WaitNotice(lambda: next(checks, False), lambda s: f"waiting {s:.2f}", first_s=0.05, period_s=0.1,
                        out=out).start()
    deadline = time.monotonic() + 30
    while notice._thread.is_alive() and time.monotonic() < deadline:
        time.sleep(0.01)
    notice.stop()
    lines = out.getvalue().splitlines()
    assert len(lines) == 2 and lines[0].startswith("waiting 0.0") and float(lines[1].split()[1]) >= 0.15 - 0.01


def test_a_lockstep_sim_without_a_controller_says_what_it_waits_for(netns):
    sim = start_sim("--clock", "lockstep", "--spawn", "standing")
    try:
        q = _lines(sim)
        first, line = _next(q, "waiting for T1_JOINT_CMD from a controller on", STARTUP_S)
        assert netns in line, line
        second, _ = _next(q, "waiting for T1_JOINT_CMD", config.WAIT_NOTICE_PERIOD_S + STARTUP_S)
        assert second - first >= config.WAIT_NOTICE_PERIOD_S - PERIOD_SLACK_S
    finally:
        _end(sim)


def test_a_runtime_without_state_says_what_it_lacks(netns):
    runtime = start_runtime(UNTRAINED, "--clock", "realtime")
    try:
        q = _lines(runtime)
        first, line = _next(q, "no T1_IMU / T1_JOINT_STATE on", STARTUP_S)
        assert netns in line and "for 1 s: is the robot or the sim running?" in line, line
        second, _ = _next(q, "no T1_IMU / T1_JOINT_STATE on", RUNTIME_REPEAT_S + STARTUP_S)
        assert second - first >= RUNTIME_REPEAT_S - PERIOD_SLACK_S
    finally:
        _end(runtime)

"""Start the project's processes (the simulator, the C++ runtime) as children of the current process, in
its network namespace. Used by the demo, the evaluation commands, the tests and the benchmarks."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BUILD = Path(os.environ.get("T1_BUILD", ROOT / "build"))
RUNTIME = BUILD / "runtime" / "t1-runtime"
LOGGER = BUILD / "sim_hil" / "core" / "t1-lcm-logger"   # sim_hil/core/lcm_logger.cpp
RUNTIME_OPEN_MARGIN_S = 0.2     # banner printed -> LCM subscribed: microseconds; this is margin


def _env() -> dict:
    return dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(BUILD / "gen" / "python")]))


def start_sim(*args: str) -> subprocess.Popen:
    """`python -m sim_hil --quiet ARGS`; stderr is kept for the caller to report. No LCM log unless ARGS name
    one with --log (callers that log, like the demo, capture the run themselves)."""
    log_args = () if "--log" in args else ("--no-log",)
    return subprocess.Popen([sys.executable, "-m", "sim_hil", "--quiet", *log_args, *args], cwd=ROOT, env=_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def start_runtime(policy: Path, *args: str) -> subprocess.Popen:
    if not RUNTIME.exists():
        raise FileNotFoundError(f"{RUNTIME} is not built: run `make build`")
    return subprocess.Popen([str(RUNTIME), "--policy", str(policy), "--quiet", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_until_listening(runtime: subprocess.Popen) -> None:
    """A lockstep peer's first state must not go out before the runtime subscribes (it would wait for an
    answer that never comes): wait for the banner the runtime prints just before it opens LCM, plus a
    margin. Reading a line at a time leaves the rest of stderr for stop()."""
    lines = []
    while True:
        line = runtime.stderr.readline()
        if not line:
            raise RuntimeError(f"t1-runtime exited before listening: {''.join(lines)}")
        lines.append(line)
        if line.startswith("t1-runtime: policy '") or "COMPOSITE mode" in line:
            break
    time.sleep(RUNTIME_OPEN_MARGIN_S)


def stop_cleanly_on_sigterm() -> None:
    """In the programs stop() ends (the sim, the demo): SIGTERM raises KeyboardInterrupt in the main thread,
    so their `finally` blocks run. Killed outright, they would leave lcm-logger running with a log that
    lacks its end marker, and the Fast DDS relay's socket open."""
    def interrupt(_signum, _frame):
        raise KeyboardInterrupt
    signal.signal(signal.SIGTERM, interrupt)


def stop(proc: subprocess.Popen, timeout_s: float = 10.0) -> tuple[int, str]:
    """SIGTERM (a clean stop for both programs), then collect the exit code and stderr."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
    try:
        _, err = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
    return proc.returncode, err

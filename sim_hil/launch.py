"""Start the project's processes (the simulator, the C++ runtime) as children of the current process, in
its network namespace. Used by the demo, the evaluation commands, the tests and the benchmarks."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BUILD = Path(os.environ.get("T1_BUILD", ROOT / "build"))
RUNTIME = BUILD / "runtime" / "t1-runtime"


def _env() -> dict:
    return dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(BUILD / "gen" / "python")]))


def start_sim(*args: str) -> subprocess.Popen:
    """`python -m sim_hil --quiet ARGS`; stderr is kept for the caller to report."""
    return subprocess.Popen([sys.executable, "-m", "sim_hil", "--quiet", *args], cwd=ROOT, env=_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def start_runtime(policy: Path, *args: str) -> subprocess.Popen:
    if not RUNTIME.exists():
        raise FileNotFoundError(f"{RUNTIME} is not built: run `make build`")
    return subprocess.Popen([str(RUNTIME), "--policy", str(policy), "--quiet", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


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

"""Start the C++ runtime (build/runtime/t1-runtime) next to the simulator, inside the namespace."""
from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RUNTIME = Path(os.environ.get("T1_BUILD", ROOT / "build")) / "runtime" / "t1-runtime"
UNTRAINED_STUDENT = ROOT / "policies" / "student_untrained.safetensors"


def start_runtime(policy: Path, *args: str) -> subprocess.Popen:
    if not RUNTIME.exists():
        raise FileNotFoundError(f"{RUNTIME} not built: run make build")
    return subprocess.Popen([str(RUNTIME), "--policy", str(policy), "--quiet", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def stop(proc: subprocess.Popen, timeout_s: float = 10.0) -> tuple[int, str]:
    """SIGTERM (the runtime's clean stop), then collect its exit code and stderr."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
    try:
        _, err = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
    return proc.returncode, err

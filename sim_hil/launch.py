"""Start the project's processes (the simulator, the C++ runtime) as children of the current process, in
its network namespace. Used by the demo, the evaluation commands, the tests and the benchmarks."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from common import keyframe_chain
from messages.auth import RunKey

ROOT = Path(__file__).resolve().parents[1]
BUILD = Path(os.environ.get("T1_BUILD", ROOT / "build"))
# $T1_RUNTIME: another build's t1-runtime (make test-sanitize drives build-asan's from the Python tests)
RUNTIME = Path(os.environ.get("T1_RUNTIME", BUILD / "runtime" / "t1-runtime"))
LOGGER = BUILD / "sim_hil" / "core" / "t1-lcm-logger"   # sim_hil/core/lcm_logger.cpp
RUNTIME_OPEN_MARGIN_S = 0.2     # banner printed -> LCM subscribed: microseconds; this is margin


def _env() -> dict:
    return dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(BUILD / "gen" / "python")]))


def start_sim(*args: str, run_key: RunKey | None = None) -> subprocess.Popen:
    """`python -m sim_hil --quiet ARGS`; stderr is kept for the caller to report. No LCM log unless ARGS name
    one with --log (callers that log, like the demo, capture the run themselves). run_key: the run's keys
    (start_runtime's run_key too): the simulator signs its state with the run's robot key (--robot-key)."""
    log_args = () if "--log" in args else ("--no-log",)
    key_args = ("--robot-key", str(run_key.robot_key_path)) if run_key is not None and "--robot-key" not in args else ()
    return subprocess.Popen([sys.executable, "-m", "sim_hil", "--quiet", *log_args, *key_args, *args], cwd=ROOT,
                            env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _value_of(args: tuple[str, ...], flag: str) -> str | None:
    return args[args.index(flag) + 1] if flag in args[:-1] else None


def start_runtime(policy: Path, *args: str, output=None, sign: bool = True,
                  run_key: RunKey | None = None) -> subprocess.Popen:
    """`t1-runtime --policy POLICY --quiet ARGS`, commanded by this run only: unless ARGS carry --key or
    --unauthenticated, a fresh key of this run (messages.auth.RunKey: a private temporary folder) is made,
    the run's policies (POLICY or a chain folder's members, --policy-upright) approved under it, and --key,
    --approvals and --policy-dir (ARGS' own, else the policies' common folder) added. The process's run_key
    signs what the caller sends (run_key.signer(); None when ARGS chose) and approves what it loads; stop()
    removes it. output: a file for stdout and stderr (default: pipes the caller reads). sign=False adds nothing: the
    runtime then takes estop only. run_key: the run's keys, made by the caller before the simulator
    (start_sim(run_key=...)): used instead of a fresh one, and its robot key added (--robot-key): the runtime takes
    state only from the simulator of this run."""
    if not RUNTIME.exists():
        raise FileNotFoundError(f"{RUNTIME} is not built: run `make build`")
    given, auth_args = run_key, []
    if given is not None and "--robot-key" not in args:
        auth_args = ["--robot-key", str(given.robot_key_path)]
    if sign and "--key" not in args and "--unauthenticated" not in args:
        policies = keyframe_chain.artifact_files(policy) + ([Path(u)] if (u := _value_of(args, "--policy-upright"))
                                                            else [])
        folder = _value_of(args, "--policy-dir") or os.path.commonpath([str(p.resolve().parent) for p in policies])
        run_key = given or RunKey()
        run_key.approve(*policies)
        auth_args += ["--key", str(run_key.key_path), "--approvals", str(run_key.approvals_path)]
        auth_args += [] if "--policy-dir" in args else ["--policy-dir", folder]
    streams = dict(stdout=output, stderr=subprocess.STDOUT) if output is not None else dict(
        stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc = subprocess.Popen([str(RUNTIME), "--policy", str(policy), "--quiet", *auth_args, *args], text=True, **streams)
    proc.run_key = run_key
    return proc


def runtime_reason(stderr_text: str) -> str:
    """The runtime's own reason for stopping: the last line it printed (its banner comes first), one line."""
    lines = [line.strip() for line in stderr_text.replace("\r", "\n").splitlines() if line.strip()]
    return lines[-1].removeprefix("t1-runtime: ") if lines else "no output"


def wait_until_listening(runtime: subprocess.Popen) -> None:
    """A lockstep peer's first state must not go out before the runtime subscribes (it would wait for an
    answer that never comes): wait for the banner the runtime prints just before it opens LCM, plus a
    margin. Reading a line at a time leaves the rest of stderr for stop()."""
    lines = []
    while True:
        line = runtime.stderr.readline()
        if not line:
            raise RuntimeError(f"t1-runtime exited before listening: {runtime_reason(''.join(lines))}")
        lines.append(line)
        if line.startswith("t1-runtime: policy '") or "COMPOSITE mode" in line or "CHAIN mode" in line:
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
    if getattr(proc, "run_key", None) is not None:
        proc.run_key.close()
    return proc.returncode, err

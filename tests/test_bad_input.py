"""Bad input where a user types it: one line naming the input, a non-zero exit, no traceback, and nothing
written or started. One row per case, each command as a user runs it from the repository root with the
project's Python and no PYTHONPATH set by hand (tools/setup.sh's .pth finds the checkout)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from sim_hil.launch import runtime_reason

ROOT = Path(__file__).resolve().parents[1]
BUILD = Path(os.environ.get("T1_BUILD", ROOT / "build"))
PY = str(ROOT / ".venv" / "bin" / "python") if (ROOT / ".venv" / "bin" / "python").exists() else sys.executable
EXIT_USAGE, EXIT_BAD_ARTIFACT = 2, 3   # the Python tools' usage error; t1-runtime's bad policy artifact
TIMEOUT_S = 120
MAX_LINES = 2                          # argparse's usage line may come before the one line of the error


def _fake(tmp: Path) -> Path:
    path = tmp / "notes.safetensors"
    path.write_text("a text file renamed .safetensors\n")
    return path


def _log(tmp: Path) -> Path:
    from sim_hil.lcmlog.eventlog import write_events
    from tests.test_lcmlog import _events
    return write_events(tmp / "run.lcmlog", _events())


# (id, argv builder (tmp folder → argv), exit code, what the message must name)
CASES = [
    ("eval-missing-policy", lambda t: [PY, "-m", "sim_hil.eval", "getup", "--policy", "NOT_AN_ARTIFACT"],
     EXIT_USAGE, "NOT_AN_ARTIFACT"),
    ("eval-fake-policy", lambda t: [PY, "-m", "sim_hil.eval", "getup", "--policy", str(_fake(t))],
     EXIT_USAGE, "notes.safetensors"),
    ("eval-folder-baseline", lambda t: [PY, "-m", "sim_hil.eval", "getup", "--policy",
                                        "policies/student_untrained/student_untrained.safetensors",
                                        "--baseline", "policies/student,policies/joystick/joystick.safetensors"],
     EXIT_USAGE, "policies/student: a folder"),
    ("demo-missing-policy", lambda t: [PY, "-m", "sim_hil.demo", "--policy", "/nonexistent"], EXIT_USAGE,
     "/nonexistent"),
    ("demo-fake-policy", lambda t: [PY, "-m", "sim_hil.demo", "--policy", str(_fake(t))], EXIT_USAGE,
     "notes.safetensors"),
    ("t1key-approve-fake", lambda t: [str(ROOT / "tools" / "t1key"), "approve", "--key", str(_key(t)),
                                      "--approvals", str(t / "approvals"), str(_fake(t))], EXIT_USAGE,
     "notes.safetensors"),
    ("teleop-negative-duration", lambda t: [PY, "-m", "sim_hil.teleop", "--keyboard", "--duration", "-1"],
     EXIT_USAGE, "--duration -1"),
    ("teleop-zero-duration", lambda t: [PY, "-m", "sim_hil.teleop", "--keyboard", "--duration", "0"],
     EXIT_USAGE, "--duration 0"),
    ("runtime-policy-folder",
     lambda t: [str(BUILD / "runtime" / "t1-runtime"), "--policy", "policies/student_untrained"],
     EXIT_BAD_ARTIFACT, "policies/student_untrained' is a folder"),
    ("lcmlog-info-folder", lambda t: [PY, "-m", "sim_hil.lcmlog", "info", "policies"], EXIT_USAGE,
     "policies: a folder"),
    ("lcmlog-plot-missing", lambda t: [PY, "-m", "sim_hil.lcmlog", "plot", "nothing.lcmlog"], EXIT_USAGE,
     "nothing.lcmlog: no such log file"),
    ("replay-fake-policy", lambda t: ["tools/netns", PY, "-m", "sim_hil.lcmlog", "replay", "--policy", str(_fake(t)),
                                      str(_log(t))], EXIT_USAGE, "notes.safetensors"),
]


def _key(tmp: Path) -> Path:
    key = tmp / "operator.key"
    subprocess.run([str(ROOT / "tools" / "t1key"), "new-key", str(key)], check=True, capture_output=True,
                   cwd=ROOT, timeout=TIMEOUT_S)
    return key


@pytest.mark.parametrize("argv, code, named", [pytest.param(a, c, n, id=i) for i, a, c, n in CASES])
def test_bad_input_is_one_line_and_a_nonzero_exit(tmp_path, argv, code, named):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    command = argv(tmp_path)
    if os.environ.get("T1_NETNS_INSIDE") == "1" and command[0] == "tools/netns":
        command = command[1:]                     # already inside the namespace
    run = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True, timeout=TIMEOUT_S)
    lines = [line for line in run.stderr.splitlines() if line.strip()]
    assert run.returncode == code, (run.returncode, run.stderr[-2000:])
    assert "Traceback" not in run.stderr + run.stdout, run.stderr[-2000:]
    assert 1 <= len(lines) <= MAX_LINES, run.stderr[-2000:]
    assert named in lines[-1], lines
    assert not (tmp_path / "approvals").exists(), "a refused approval wrote the approvals file"


def test_a_failed_replay_names_the_runtimes_reason_first():
    banner = ("t1-runtime: commands: estop only (no --key): every other runtime_cmd_t and the joystick are refused\n"
              "t1-runtime: refused: policy 'x.safetensors' not loaded: no approval for its SHA-256\n")
    assert runtime_reason(banner) == "refused: policy 'x.safetensors' not loaded: no approval for its SHA-256"
    assert runtime_reason("\rPOLICY ticks 3 | age imu 1.0\rPOLICY ticks 4\nt1-runtime: stopped\n") == "stopped"
    assert runtime_reason("") == "no output"

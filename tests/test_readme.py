"""The README's commands run as written, so the README cannot rot: every command line in it (its bash blocks
and its `inline` commands) is read here. Each names files that exist, uses the project's Python (never a bare
`python`), each module and program it runs answers --help from the repository root with no PYTHONPATH set by
hand, each make target exists, and the two examples that run a simulator (the DDS robot link, the simulator's
quick reference) run to their end inside the namespace."""
from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
HELP_TIMEOUT_S = 300           # `python -m training --help` imports JAX: tens of seconds on a loaded machine
EXAMPLE_TIMEOUT_S = 300        # a few seconds of simulation each, plus start-ups under load
COMMANDS = (".venv/bin/python", "tools/", "build/", "make ", "python ", "python3 ")
REPO_PATH = re.compile(r"(?<![\w/~.$-])((?:policies|tools|runtime|sim_hil|messages|common|training|docs|tests|"
                       r"firmware_like|build)/[\w./-]*\w)")
PLACEHOLDER = re.compile(r"…|\.\.\.|<|\*|NAME|\{")


def _blocks() -> list[str]:
    """Each ```bash block's text."""
    return re.findall(r"```bash\n(.*?)```", README, flags=re.S)


def _commands() -> list[str]:
    """Every command: the lines of the bash blocks (continuations joined, comments cut) and the inline spans that
    start like a command."""
    lines = []
    for block in _blocks():
        lines += [line.split("  #")[0].strip() for line in block.replace("\\\n", " ").splitlines()]
    lines += [span.strip() for span in re.findall(r"`([^`\n]+)`", README)]
    lines = [re.sub(r"^tools/netns (bash -c ')?", "", line) for line in lines]
    return [line for line in lines if line.startswith(COMMANDS) or " .venv/bin/python " in f" {line} "]


def _env() -> dict:
    return {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}


def test_commands_use_the_projects_python():
    bare = [c for c in _commands() if re.match(r"python3? ", c)]
    assert not bare, f"bare python in the README (use .venv/bin/python): {bare}"


def test_named_files_exist():
    named = {m for c in _commands() for m in REPO_PATH.findall(c) if not PLACEHOLDER.search(m)}
    named |= {m for c in re.findall(r"[A-Z_]+=([\w./,-]+)", README) for m in REPO_PATH.findall(c)}
    assert named, "no file named: the README's parsing broke"
    missing = sorted(p for p in named if not (ROOT / p.rstrip(".")).exists())
    assert not missing, f"the README names files that do not exist: {missing}"


def test_make_targets_exist():
    targets = set(re.findall(r"^([\w.-]+):", (ROOT / "Makefile").read_text(), flags=re.M))
    named = set(re.findall(r"`make ([\w.-]*\w)(?![\w*-])", README)) | set(re.findall(r"`(eval-[\w.-]+)`", README))
    assert named and not sorted(named - targets), sorted(named - targets)


def _runnables() -> list[list[str]]:
    """What each command runs, as a --help call: `python -m MODULE`, build/runtime/t1-runtime, tools/t1key."""
    modules = sorted({m for c in _commands() for m in re.findall(r"\.venv/bin/python -m ([\w.]+)", c)})
    program = re.compile(r"(?:^|\s)(build/runtime/t1-runtime|tools/t1key)\b")
    programs = sorted({p for c in _commands() for p in program.findall(c)})
    return [[".venv/bin/python", "-m", m, "--help"] for m in modules] + [[p, "--help"] for p in programs]


@pytest.mark.parametrize("argv", _runnables(), ids=lambda a: " ".join(a[:-1]))
def test_each_command_answers_help(argv):
    run = subprocess.run(argv, cwd=ROOT, env=_env(), capture_output=True, text=True, timeout=HELP_TIMEOUT_S)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "usage" in (run.stdout + run.stderr).lower(), run.stdout[-500:]


def _example(marker: str) -> str:
    found = [b for b in _blocks() if marker in b]
    assert len(found) == 1, f"{len(found)} README blocks with {marker!r}"
    return found[0]


@pytest.mark.parametrize("marker, ends_with", [
    ("--transport dds --clock lockstep", "t1-runtime: stopped"),
    ("--scenario walls --spawn fallen:7", None)], ids=["dds-link", "simulator-quick-reference"])
def test_the_simulator_examples_run_to_their_end(netns, marker, ends_with):
    run = subprocess.run(["bash", "-c", _example(marker)], cwd=ROOT, env=_env(), capture_output=True, text=True,
                         timeout=EXAMPLE_TIMEOUT_S)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "Traceback" not in run.stderr, run.stderr[-3000:]
    if ends_with:
        assert ends_with in run.stderr, run.stderr[-3000:]

"""A PPO run killed mid-call (a session cut off, SIGKILL): what it wrote at its last checkpoint is enough to
say what made that checkpoint. (The DAgger counterpart needs the toy runs: test_training_cli.py.)"""
import json

import pytest

from tests.test_training_cli import TOY_STEPS, run_until_killed
from training.core import checkpoints


@pytest.mark.slow
def test_a_killed_run_keeps_its_call_record(tmp_path):
    """The call's record (command, steps, minutes) is written with every checkpoint, so --resume and the
    run's PROGRESS still know what made the newest checkpoint."""
    run_dir = tmp_path / "killed"
    state_file = run_dir / checkpoints.RUN_STATE
    run_until_killed(["train", "joystick", "--steps", str(10_000 * TOY_STEPS), "--out", str(run_dir), "--toy",
                      "--no-progress"],
                     ready=lambda: state_file.exists() and json.loads(state_file.read_text())["env_steps"] > 0)
    state = json.loads(state_file.read_text())
    (call,) = state["calls"]
    assert "train joystick" in call["command"] and call["finished"] is False
    assert call["to_steps"] == state["env_steps"] == checkpoints.checkpoint_steps(run_dir) > 0
    assert state["minutes"] == pytest.approx(call["minutes"], abs=0.01) and call["minutes"] > 0

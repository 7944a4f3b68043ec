"""`python -m training`: config overrides, provenance table, and (slow, CPU toy scale) PPO runs for every
task with a resume, a DAgger distillation, a batched getup evaluation and the runtime accepting the
exported artifacts.

The slow tests share one module-scoped set of toy runs (tiny networks, 8 envs, 0.4 s episodes): the cost
is jit compilation of the MJX step (minutes on this CPU), which the persistent compilation cache
(build/jax_cache, training/core/checkpoints.jax_setup) makes a one-time cost per machine.
"""
import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from ml_collections import config_dict

from common.artifact import read_artifact
from training import cli
from training.core import checkpoints, curves, overrides

ROOT = Path(__file__).resolve().parent.parent
RUNTIME = Path(os.environ.get("T1_BUILD", ROOT / "build")) / "runtime" / "t1-runtime"
RUNTIME_BAD_ARTIFACT_EXIT = 3
TOY_STEPS = 80          # one toy PPO training step: 8 envs × 5 unroll × 2 minibatches


# ---------------------------------------------------------------- fast
def test_config_overrides_prefixed_bare_and_errors():
    ppo = config_dict.create(learning_rate=3e-4, hidden=(8, 8))
    env = config_dict.create(episode_length=1000, noise=config_dict.create(level=1.0))
    overrides.apply_overrides({"ppo": ppo, "env": env}, ["learning_rate=1e-4", "env.noise.level=0.5",
                                                   "ppo.hidden=(4, 4)", "episode_length=20"])
    assert ppo.learning_rate == 1e-4 and tuple(ppo.hidden) == (4, 4)
    assert env.noise.level == 0.5 and env.episode_length == 20
    with pytest.raises(ValueError, match="no config"):
        overrides.apply_overrides({"ppo": ppo, "env": env}, ["nonexistent=1"])
    with pytest.raises(ValueError, match="key=value"):
        overrides.apply_overrides({"ppo": ppo}, ["learning_rate"])
    with pytest.raises(ValueError, match="has no field"):
        overrides.apply_overrides({"ppo": ppo, "env": env}, ["env.missing=1"])


def test_config_overrides_take_json_booleans():
    env = config_dict.create(enabled=True, deterministic=False)
    overrides.apply_overrides({"env": env}, ["env.enabled=false", "env.deterministic=True"])
    assert env.enabled is False and env.deterministic is True
    with pytest.raises(ValueError, match="enabled=maybe"):
        overrides.apply_overrides({"env": env}, ["env.enabled=maybe"])


def test_cli_rejects_bad_usage(capsys):
    with pytest.raises(SystemExit):
        cli.main(["train", "not_a_task", "--out", "/tmp/x"])
    assert cli.main(["train", "joystick", "--out", "/nonexistent/run", "--resume", "--no-progress"]) == 2
    assert "no run to resume" in capsys.readouterr().err
    assert cli.main(["evaluate", "--task", "joystick", "--policy", "a.safetensors", "--baseline", "b"]) == 2
    assert "joystick evaluation takes one policy" in capsys.readouterr().err
    assert cli.main(["train", "joystick", "--out", "/nonexistent/run", "--resume", "--no-progress",
                     "--config", "ppo.learning_rate=1"]) == 2
    assert "only checkpoint_every_steps" in capsys.readouterr().err


def test_a_cards_provenance_table_appends_rows(tmp_path):
    table = tmp_path / checkpoints.CARD
    row = {c: f"v{i}" for i, c in enumerate(checkpoints.PROVENANCE_COLUMNS)}
    checkpoints.append_provenance_row(row, table)
    checkpoints.append_provenance_row({**row, "command": "a|b"}, table)
    lines = table.read_text().splitlines()
    assert lines[0] == f"# {row['name']}" and "## Provenance" in lines   # a new policy's card, from the template
    body = [ln for ln in lines if ln.startswith("| v0")]
    assert len(body) == 2 and "a\\|b" in body[1]
    with pytest.raises(ValueError, match="missing column"):
        checkpoints.provenance_row({"date": "x"})


# ---------------------------------------------------------------- slow: toy runs (CLI subprocesses)
TOY_ENV = {**os.environ,       # XLA_FLAGS: tests/conftest.py's (compile fast, run slow: right for toy runs)
           "PYTHONPATH": f"{ROOT}:{ROOT / 'build' / 'gen' / 'python'}"}
MAX_PARALLEL = 2  # the CI machine has 2 cores; XLA compilation is mostly single-threaded


def run_until_killed(args: list, ready, timeout_s: float = 600.0) -> None:
    """Start `python -m training ARGS`, kill it (SIGKILL, as a session cut off) once `ready()` holds; fails if
    it ended before that."""
    import sys
    import time
    proc = subprocess.Popen([sys.executable, "-m", "training", *args], cwd=ROOT, env=TOY_ENV,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and proc.poll() is None and not ready():
            time.sleep(0.5)
        assert proc.poll() is None, f"{args[:2]} ended before it was ready to be killed"
    finally:
        proc.kill()
        proc.wait()


def _run_parallel(commands: dict) -> dict:
    """Run `python -m training ...` command lists, MAX_PARALLEL at a time; name → stdout. Fails loudly."""
    import sys
    out, pending = {}, list(commands.items())
    while pending:
        batch, pending = pending[:MAX_PARALLEL], pending[MAX_PARALLEL:]
        procs = {name: subprocess.Popen([sys.executable, "-m", "training", *args], cwd=ROOT, env=TOY_ENV,
                                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
                 for name, args in batch}
        for name, proc in procs.items():
            text = proc.communicate(timeout=900)[0]
            assert proc.returncode == 0, f"{name}: exit {proc.returncode}\n{text[-4000:]}"
            out[name] = text
    return out


@pytest.fixture(scope="module")
def toy_runs(tmp_path_factory):
    """Toy PPO runs of every task (joystick twice: the second call resumes it), a distillation and an
    evaluation, all through the CLI. Returns {name: run directory or output folder}."""
    root = tmp_path_factory.mktemp("toy_runs")
    dirs = {t: root / t for t in ("joystick", "getup_stand", "getup_baseline")}
    toy = ["--toy", "--no-progress", "--seed", "1"]
    _run_parallel({
        "joystick": ["train", "joystick", "--steps", str(TOY_STEPS), "--out", str(dirs["joystick"]), *toy],
        "getup_stand": ["train", "getup_stand", "--steps", str(TOY_STEPS), "--out", str(dirs["getup_stand"]), *toy]})
    dirs["boxed"], dirs["student"], dirs["eval"] = root / "boxed", root / "student", root / "eval"
    dirs["joystick_first"] = json.loads((dirs["joystick"] / checkpoints.RUN_STATE).read_text())["env_steps"]
    _run_parallel({
        # a critic-only warm-up step, then a PPO step (two ppo.train calls, one run)
        "getup_baseline": ["train", "getup_baseline", "--steps", str(2 * TOY_STEPS), "--config",
                           f"ppo.value_warmup_steps={TOY_STEPS}", "--out", str(dirs["getup_baseline"]), *toy],
        "resume": ["train", "joystick", "--resume", "--steps", str(2 * TOY_STEPS), "--out", str(dirs["joystick"]),
                   "--no-progress"],
        # the other PPO runs take the default backend (cpu here: no GPU); this one keeps MJX's PPO path tested
        "boxed": ["train", "joystick", "--backend", "mjx", "--steps", str(50 * TOY_STEPS), "--max-minutes", "0",
                  "--out", str(dirs["boxed"]), *toy],
        "distill": ["distill", "--getup", str(dirs["getup_stand"] / "getup_stand.safetensors"), "--joystick",
                    str(dirs["joystick"]), "--out", str(dirs["student"]), "--config", "env.start_probs=(0.0, 0.5, 0.5)",
                    # default --task: the unified env (no fallen starts: their precompute is slow)
                    "--name", "student_toy", *toy],
        # the keyframe chain as the teacher (each member the toy stand policy: a getup-layout artifact)
        "distill_chain": ["distill", "--chain", ",".join([str(dirs["getup_stand"] / "getup_stand.safetensors")] * 3),
                          "--task", "getup", "--out", str(root / "chain_distill"), "--config",
                          "env.start_probs=(0.0, 0.5, 0.5)", "--name", "chain_toy", *toy]})
    dirs["chain_distill"] = root / "chain_distill"
    dirs["eval_joystick"] = root / "eval_joystick"
    _run_parallel({"evaluate": ["evaluate", "--policy", str(dirs["getup_stand"] / "getup_stand.safetensors"),
                                "--baseline", str(dirs["getup_baseline"] / "getup_baseline.safetensors"),
                                "--seeds", "2", "--seconds", "0.2", "--out", str(dirs["eval"])],
                   "evaluate_joystick": ["evaluate", "--task", "joystick", "--policy",
                                         str(dirs["joystick"] / "joystick.safetensors"), "--seeds", "2",
                                         "--seconds", "0.2", "--out", str(dirs["eval_joystick"])]})
    return dirs


def _artifact(run_dir: Path) -> Path:
    found = sorted(run_dir.glob("*.safetensors"))
    assert len(found) == 1, f"{run_dir}: expected one exported artifact, found {found}"
    return found[0]


def test_the_epoch_after_a_calls_first_is_estimated_from_its_throughput():
    """A call's first epoch holds the compilation: --max-minutes must not take it for the next epoch's length
    (a 7-minute GPU call stopped after 5 M of its 40 M steps that way), but never estimate longer than it."""
    from training.ppo.train import FIRST_EPOCH_MARGIN, next_epoch_estimate_s
    assert next_epoch_estimate_s(300.0, 5_000_000, 100_000.0, first_of_call=True) == FIRST_EPOCH_MARGIN * 50.0
    assert next_epoch_estimate_s(30.0, 5_000_000, 100_000.0, first_of_call=True) == 30.0
    assert next_epoch_estimate_s(300.0, 5_000_000, None, first_of_call=True) == 300.0       # no throughput yet
    assert next_epoch_estimate_s(60.0, 5_000_000, 100_000.0, first_of_call=False) == 60.0    # measured


@pytest.mark.slow
@pytest.mark.parametrize("task", ["joystick", "getup_stand", "getup_baseline"])
def test_toy_ppo_run_exports_an_artifact(toy_runs, task):
    run_dir = toy_runs[task]
    state = json.loads((run_dir / checkpoints.RUN_STATE).read_text())
    assert state["env_steps"] >= state["target_steps"] > 0
    layers, mean, std, manifest = read_artifact(_artifact(run_dir))
    assert manifest["trained"] is False, "toy runs must never claim to be trained"
    assert manifest["provenance"]["steps"] == state["env_steps"]
    assert manifest["provenance"]["device"].startswith("cpu") and manifest["provenance"]["git_commit"]
    assert [list(t) for t in manifest["obs_terms"]] == [list(t) for t in state["env_config"]["obs_terms"]]
    assert layers[0][0].shape == (16, mean.shape[0]) and np.all(std > 0)
    assert (run_dir / curves.CSV_NAME).exists() and list((run_dir / "tensorboard").iterdir())
    assert (run_dir / curves.PNG_NAME).exists()
    assert checkpoints.list_checkpoints(run_dir)
    assert state["calls"][0]["backend"] == "cpu"     # the default without a GPU: MuJoCo C
    if task == "getup_baseline":   # both phases logged onto one curve
        steps = {s for s, _ in max(curves.read_curves(run_dir / curves.CSV_NAME).values(), key=len)}
        assert min(steps) <= TOY_STEPS < max(steps)


@pytest.mark.slow
def test_resume_continues_step_count_and_curve(toy_runs):
    run_dir, first = toy_runs["joystick"], toy_runs["joystick_first"]
    state = json.loads((run_dir / checkpoints.RUN_STATE).read_text())
    assert state["env_steps"] >= 2 * TOY_STEPS > first
    assert [c["from_steps"] for c in state["calls"]] == [0, first]
    steps = [s for s, _ in max(curves.read_curves(run_dir / curves.CSV_NAME).values(), key=len)]
    assert max(steps) > first, "the resumed call's metrics continue the curve"
    assert checkpoints.checkpoint_steps(run_dir) == state["env_steps"]
    assert read_artifact(_artifact(run_dir))[3]["provenance"]["steps"] == state["env_steps"]


@pytest.mark.slow
def test_max_minutes_stops_at_a_checkpoint(toy_runs):
    state = json.loads((toy_runs["boxed"] / checkpoints.RUN_STATE).read_text())
    assert 0 < state["env_steps"] < state["target_steps"] and state["calls"][-1]["stopped_by_max_minutes"]
    assert state["calls"][-1]["finished"]
    assert checkpoints.checkpoint_steps(toy_runs["boxed"]) == state["env_steps"]
    assert read_artifact(_artifact(toy_runs["boxed"]))[3]["provenance"]["steps"] == state["env_steps"]


@pytest.mark.slow
def test_toy_distill_exports_student(toy_runs):
    from common import observation as obsdef
    # the toy run used distill's default env: the unified walk–fall–getup task
    assert cli.build_parser().parse_args(["distill", "--getup", "g", "--joystick", "j", "--out", "o"]).task == "unified"
    layers, _, _, manifest = read_artifact(toy_runs["student"] / "student_toy.safetensors")
    assert manifest["name"] == "student_toy"
    # the seed's raw actions (no tanh squash): the loc half of brax's head, output rule linear
    assert manifest["output_rule"] == "linear" and manifest["trained"] is False
    assert [tuple(t) for t in manifest["obs_terms"]] == list(obsdef.TERMS_UNION)
    assert layers[-1][0].shape[0] == obsdef.NUM_JOINTS and manifest["provenance"]["steps"] > 0
    assert manifest["provenance"]["env_steps_per_s"] > 0     # the provenance table's env-steps/s column


@pytest.mark.slow
def test_toy_distill_from_the_keyframe_chain_exports_a_getup_policy(toy_runs):
    from common import observation as obsdef
    _, _, _, manifest = read_artifact(toy_runs["chain_distill"] / "chain_toy.safetensors")
    assert [tuple(t) for t in manifest["obs_terms"]] == list(obsdef.TERMS_GETUP)    # the task's own terms
    assert set(manifest["provenance"]["teacher"]) == {"roll", "rise", "stand"} and manifest["trained"] is False


@pytest.mark.slow
def test_export_phase_writes_an_earlier_checkpoint(toy_runs, capsys):
    from training.distill.dagger import export_phase
    run = toy_runs["student"]
    final_layers, _, _, final = read_artifact(run / "student_toy.safetensors")
    phases = final["provenance"]["dagger_phases"]   # the toy run keeps one checkpoint: its last phase
    layers, _, _, again = read_artifact(export_phase(run, phases, "student_again"))   # like: the state file's
    assert again["name"] == "student_again" and again["provenance"]["steps"] == final["provenance"]["steps"]
    assert again["obs_terms"] == final["obs_terms"] and again["output_rule"] == final["output_rule"]
    assert again["trained"] is False and all(np.array_equal(w, v) for (w, _), (v, _) in zip(layers, final_layers))
    assert cli.main(["export-phase", "--run", str(run), "--phase", "3", "--name", "x",
                     "--like", str(run / "student_toy.safetensors")]) == 2
    assert "no checkpoint at phase 3" in capsys.readouterr().err


@pytest.mark.slow
def test_export_checkpoint_writes_an_earlier_epoch(toy_runs, capsys):
    from training.ppo.train import export_checkpoint
    run, first = toy_runs["joystick"], toy_runs["joystick_first"]   # resumed: checkpoints at two step counts
    final_layers, _, _, final = read_artifact(run / "joystick.safetensors")
    path = export_checkpoint(run, first, "joystick_early")
    layers, _, _, early = read_artifact(path)
    path.unlink()   # the shared toy run keeps one artifact (test_runtime_accepts_exported_artifacts)
    assert early["name"] == "joystick_early" and early["provenance"]["steps"] == first < final["provenance"]["steps"]
    assert early["obs_terms"] == final["obs_terms"] and early["trained"] is False     # a toy run stays untrained
    assert not all(np.array_equal(w, v) for (w, _), (v, _) in zip(layers, final_layers))
    assert cli.main(["export-checkpoint", "--run", str(run), "--steps", "7", "--name", "x"]) == 2
    assert "no checkpoint at 7 env steps" in capsys.readouterr().err
    # several: the mean of their policies' parameters (the export maps parameters linearly to layers)
    path = export_checkpoint(run, [first, final["provenance"]["steps"]], "joystick_mean")
    mean_layers, _, _, mean = read_artifact(path)
    path.unlink()
    assert mean["provenance"]["steps"] == final["provenance"]["steps"] and "mean" in mean["provenance"]["exported_from"]
    for (m, _), (a, _), (b, _) in zip(mean_layers, layers, final_layers):
        np.testing.assert_allclose(m, (a + b) / 2, rtol=1e-5, atol=1e-6)


@pytest.mark.slow
def test_export_checkpoint_mid_run_takes_env_fields_from_the_from_run(toy_runs, tmp_path):
    """A run still going has no export yet: the manifest's env fields come from its --from run's export,
    the provenance from its own state."""
    import shutil

    from training.ppo.train import export_checkpoint
    parent = toy_runs["joystick"]
    child = tmp_path / "child"
    shutil.copytree(parent / checkpoints.CHECKPOINT_DIR, child / checkpoints.CHECKPOINT_DIR)
    state = json.loads((parent / checkpoints.RUN_STATE).read_text())
    steps = toy_runs["joystick_first"]
    state.update(name="child", init=str(checkpoints.checkpoint_path(parent, steps)),
                 calls=[{**state["calls"][-1], "command": "the child's command"}])
    checkpoints.save_run_state(child, state)
    _, _, _, mid = read_artifact(export_checkpoint(child, steps, "child_mid"))
    _, _, _, like = read_artifact(parent / "joystick.safetensors")
    assert mid["name"] == "child_mid" and mid["obs_terms"] == like["obs_terms"]
    assert mid["default_pose"] == like["default_pose"] and mid["action_scale"] == like["action_scale"]
    assert mid["provenance"]["steps"] == steps and mid["provenance"]["command"] == "the child's command"
    state["init"] = ""
    checkpoints.save_run_state(child, state)
    with pytest.raises(FileNotFoundError, match="no export of the run"):
        export_checkpoint(child, steps, "child_mid2")


@pytest.mark.slow
def test_distill_goes_on_from_a_run(toy_runs, tmp_path, capsys):
    """--from: a new run starts from the old run's newest checkpoint; phases, steps and curve continue."""
    from training.distill.dagger import STATE_FILE
    first = json.loads((toy_runs["student"] / STATE_FILE).read_text())
    out = tmp_path / "more"
    args = ["distill", "--getup", str(toy_runs["getup_stand"] / "getup_stand.safetensors"), "--joystick",
            str(toy_runs["joystick"]), "--config", "env.start_probs=(0.0, 0.5, 0.5)", "--toy", "--no-progress",
            "--from", str(toy_runs["student"])]
    assert cli.main([*args, "--out", str(out)]) == 0
    state = json.loads((out / STATE_FILE).read_text())
    assert state["phases"] == 2 * first["phases"] and state["steps"] == 2 * first["steps"]
    assert state["phases_before"] == first["phases"] and state["from"].endswith(f"{first['phases']:012d}")
    prov = read_artifact(out / "student.safetensors")[3]["provenance"]
    assert prov["dagger_phases"] == state["phases"] and prov["steps"] == state["steps"]
    assert min(s for s, _ in max(curves.read_curves(out / curves.CSV_NAME).values(), key=len)) > first["steps"] - 1
    assert cli.main([*args, "--out", str(out)]) == 2          # never into a run that has checkpoints
    assert "already holds DAgger checkpoints" in capsys.readouterr().err


@pytest.mark.slow
def test_a_killed_distillation_goes_on_from_its_newest_checkpoint(toy_runs, tmp_path):
    """A DAgger run killed mid-call (a session cut off) has written its state when it started: --from
    continues the phase and step count from its newest checkpoint."""
    from training.distill.dagger import STATE_FILE, prior_progress
    first = json.loads((toy_runs["student"] / STATE_FILE).read_text())
    run_dir = tmp_path / "killed"
    run_until_killed(["distill", "--getup", str(toy_runs["getup_stand"] / "getup_stand.safetensors"), "--joystick",
                      str(toy_runs["joystick"]), "--config", "env.start_probs=(0.0, 0.5, 0.5)", "--config",
                      "bc.dagger_steps=2000", "--config", "bc.num_evals=1001", "--toy", "--no-progress",
                      "--from", str(toy_runs["student"]), "--out", str(run_dir)],
                     ready=lambda: len(checkpoints.list_checkpoints(run_dir)) >= 2)
    state = json.loads((run_dir / STATE_FILE).read_text())
    assert state["finished"] is False and "distill" in state["command"]
    assert state["phases_before"] == first["phases"] and state["steps_before"] == first["steps"]
    newest = checkpoints.list_checkpoints(run_dir)[-1]
    at = prior_progress(run_dir)
    assert at["checkpoint"] == str(newest.resolve())
    assert at["phases"] == first["phases"] + int(newest.name) > first["phases"]
    assert at["steps"] == first["steps"] + int(newest.name) * state["steps_per_phase"]


@pytest.mark.slow
def test_evaluate_two_seeds_writes_the_table(toy_runs):
    text = (toy_runs["eval"] / "report.md").read_text()
    assert "| success rate |" in text and "1605.0" in text and "2279.8" in text
    assert "NO (untrained placeholder)" in text
    assert (toy_runs["eval"] / "heights.png").exists() and (toy_runs["eval"] / "table_4_3.png").exists()
    assert "| Average Max Energy |" in text and "same direction" in text
    rows = (toy_runs["eval"] / "per_env.csv").read_text().splitlines()
    assert len(rows) == 1 + 2 * 2


@pytest.mark.slow
def test_evaluate_joystick_writes_the_tracking_table(toy_runs):
    text = (toy_runs["eval_joystick"] / "report.md").read_text()
    assert "| fall rate |" in text and "RMS yaw-rate error" in text and "trained: **NO**" in text
    rows = (toy_runs["eval_joystick"] / "per_episode.csv").read_text().splitlines()
    assert len(rows) == 1 + 2


@pytest.mark.slow
def test_runtime_accepts_exported_artifacts(netns, toy_runs):
    if not RUNTIME.exists():
        pytest.skip(f"{RUNTIME} not built (make build)")
    artifacts = [_artifact(toy_runs[t]) for t in ("joystick", "getup_stand", "getup_baseline")]
    for path in artifacts + [toy_runs["student"] / "student_toy.safetensors"]:
        proc = subprocess.run([str(RUNTIME), "--policy", str(path), "--clock", "lockstep", "--duration", "0.1",
                               "--quiet"], capture_output=True, text=True, timeout=30)
        assert proc.returncode != RUNTIME_BAD_ARTIFACT_EXIT, f"{path.name}: {proc.stderr}"
        assert proc.returncode == 0, f"{path.name}: exit {proc.returncode}: {proc.stderr}"

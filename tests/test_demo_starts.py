"""Backplay starts (training/envs/starts/demos.py): states of the planner's demonstrations from the last window
before each one's end (its gate held) or arrival at the kneel, as a share of the getup env's fallen starts."""
from __future__ import annotations

import shutil

import jax
import numpy as np
import pytest

from training import envs
from training.envs.starts import demos

DEMOS = "training/campaigns/getup_keyframe/demos"      # the kneel campaign's demonstrations (the planner's)


def _arrived():
    """{file: (qpos, window's end, ctrl_dt)} of the campaign's demonstrations that reached the kneel."""
    out = {}
    for f in sorted((demos.REPO_ROOT / DEMOS).glob(demos.DEMO_GLOB)):
        with np.load(f) as z:
            end = demos.window_end(z["trunk_height"], z["kneeling"], z["gate"])
            if end is not None:
                out[f] = (z["qpos"], end, float(z["ctrl_dt"]))
    return out


def test_a_window_ends_where_the_gate_was_held_else_at_the_arrival():
    h = np.array([0.2, 0.3, 0.40, 0.40, 0.40, 0.40])
    kneeling = np.array([0, 0, 1, 1, 1, 1], bool)
    assert demos.window_end(h, kneeling, np.zeros(6, bool)) == 2                     # arrived, never gated
    assert demos.window_end(h, kneeling, np.array([0, 0, 0, 1, 1, 0], bool)) == 5    # the goal: its last step
    assert demos.window_end(h, np.zeros(6, bool), np.ones(6, bool)) is None         # never kneeling


def test_the_bank_holds_states_from_the_window_before_each_end():
    arrived = _arrived()
    assert arrived, f"{DEMOS}: no demonstration reached the kneel"
    window_s = 0.2
    allowed = np.concatenate([q[max(0, end - round(window_s / dt)):end + 1] for q, end, dt in arrived.values()])
    qpos, qvel = demos.demo_bank(DEMOS, window_s, 64, 1)
    assert qpos.shape == (64, allowed.shape[1]) and qvel.shape[0] == 64 and not qpos.flags.writeable
    assert all(np.any(np.all(allowed == row, axis=1)) for row in qpos)
    wider = demos.demo_bank(DEMOS, 2.0, 64, 1)[0]
    assert len(np.unique(wider, axis=0)) > len(np.unique(qpos, axis=0))     # the window moves the starts back
    assert np.array_equal(demos.demo_bank(DEMOS, window_s, 64, 1)[0], qpos)   # seeded


def test_gated_only_draws_from_the_demonstrations_that_met_the_gate(tmp_path):
    gated, arrived_only = [], []
    for f in sorted((demos.REPO_ROOT / DEMOS).glob(demos.DEMO_GLOB)):
        with np.load(f) as z:
            if demos.met_gate(z["gate"], z["kneeling"]):
                gated.append(z["qpos"][-round(0.2 / float(z["ctrl_dt"])) - 1:])
            elif demos.arrival_step(z["trunk_height"], z["kneeling"]) is not None:
                arrived_only.append(f)
    assert gated and arrived_only, "the campaign's demonstrations: some met the gate, some only arrived"
    qpos, _ = demos.demo_bank(DEMOS, 0.2, 64, 1, gated_only=True)
    allowed = np.concatenate(gated)
    assert all(np.any(np.all(allowed == row, axis=1)) for row in qpos)
    shutil.copy(arrived_only[0], tmp_path / "demo_0.npz")
    assert len(demos.demo_bank(str(tmp_path), 0.5, 8, 0)[0]) == 8
    with pytest.raises(ValueError, match="none of its 1 demonstrations met the gate"):
        demos.demo_bank(str(tmp_path), 0.5, 8, 0, gated_only=True)


def test_bad_folders_and_settings_are_named(tmp_path):
    with pytest.raises(ValueError, match="no demo_"):
        demos.demo_bank(str(tmp_path), 0.5, 8, 0)
    with pytest.raises(ValueError, match="window_s"):
        demos.demo_bank(DEMOS, 0.0, 8, 0)
    f, (qpos, end, _) = next(iter(_arrived().items()))
    with np.load(f) as z:         # a real demonstration cut before its arrival
        np.savez(tmp_path / "demo_0.npz", **{k: z[k][:end] if z[k].ndim else z[k] for k in z.files})
    with pytest.raises(ValueError, match="none of its 1 demonstrations reached the kneel"):
        demos.demo_bank(str(tmp_path), 0.5, 8, 0)
    (tmp_path / "demo_1.npz").write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="demo_1.npz is not a planner demonstration"):
        demos.demo_bank(str(tmp_path), 0.5, 8, 0)
    with pytest.raises(ValueError, match="demo_starts.prob > 0 needs demo_starts.folder"):
        envs.make("getup_kneel", config_overrides={"fallen.bank_starts": 2, "demo_starts.prob": 0.5})


@pytest.mark.parametrize("task", ["getup_kneel", "getup"])
def test_the_task_starts_its_fallen_episodes_from_the_demonstrations(tmp_path, task):
    """The kneel task (its backplay) and the full task (the keyframe chain's distillation) alike."""
    folder = tmp_path / "demos"
    shutil.copytree(demos.REPO_ROOT / DEMOS, folder)
    env = envs.make(task, config_overrides={"start_probs": [1.0, 0.0, 0.0],
        "backend": "cpu", "fallen.bank_starts": 2, "demo_starts.prob": 1.0,
        "demo_starts.folder": str(folder), "demo_starts.bank_starts": 8})
    qpos, qvel = demos.demo_bank(str(folder), 0.5, 8, int(env._config.demo_starts.seed))
    reset = jax.jit(jax.vmap(env.reset))
    state = reset(jax.random.split(jax.random.PRNGKey(0), 6))
    assert np.abs(np.asarray(state.data.qvel)).max() > 0.1      # mid-rise states, not settled ones
    for q, v in zip(np.asarray(state.data.qpos), np.asarray(state.data.qvel)):
        i = int(np.argmin(np.abs(qpos - q).sum(1)))
        np.testing.assert_allclose(q, qpos[i], atol=1e-6)
        np.testing.assert_allclose(v, qvel[i], atol=1e-6)      # moving: the rise's velocities come along

"""The getup tasks step as recorded: seeded resets and steps of each task on the CPU backend, in the settings the
recipes use (the kneel's backplay with demonstration starts, the sagittal action space, the gate and slope
rewards; the kneel from kneeling starts; the stand task's reverse curriculum; the full task with the energy
term and observation noise; the baseline with standing starts), give the rewards, observations, ends and metrics of
tests/golden/getup_task_steps.npz. The file was written when each getup stage got a task of its own, after
checking these steps against the one getup env they replaced (equal but for the split of its kneel Height Reward
into terms, and the stand task's per-step critic gate). A deliberate change of a task rewrites its cases (all
without names; the other cases stay as stored):

    PYTHONPATH=.:build/gen/python .venv/bin/python -m tests.test_getup_steps [CASE ...]
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

GOLDEN = Path(__file__).resolve().parent / "golden" / "getup_task_steps.npz"
DEMOS = "training/campaigns/getup_keyframe/demos"
BACKPLAY = {"fallen.bank_starts": 2, "demo_starts.prob": 0.5, "demo_starts.folder": DEMOS, "demo_starts.bank_starts": 8,
            "demo_starts.window_s": 2.0, "demo_starts.gated_only": True, "action_space": "sagittal",
            "reward.scales.gate": 1.0, "reward.scales.upright": 1.0, "reward.scales.energy": -0.01}
# case: (task, config overrides, actions around the kneel keyframe's targets)
CASES = {
    "kneel_backplay": ("getup_kneel", BACKPLAY, False),
    "kneel_from_kneeling": ("getup_kneel", {"fallen.bank_starts": 2, "start_probs": [0.5, 0.5, 0.0],
                                            "reward.scales.gate": 1.0, "reward.scales.upright": 1.0}, True),
    "stand_curriculum": ("getup_stand", {"reverse_curriculum.max_progress": 2.0, "reward.scales.energy": -0.01}, True),
    "full": ("getup", {"fallen.bank_starts": 2, "reward.scales.energy": -0.01, "obs_noise_scale": 1.0}, True),
    "baseline": ("getup_baseline", {"fallen.bank_starts": 2, "start_probs": [0.8, 0.0, 0.2],
                                    "reward.scales.energy": -0.01}, False),
}
BATCH, STEPS, ACTION_NOISE = 4, 4, 0.1
RTOL, ATOL = 1e-4, 1e-5     # XLA's optimisation level (tests run at -O0) moves the last float32 digits


def record(task: str, overrides: dict, hold_kneel: bool) -> dict[str, np.ndarray]:
    """{series name: (STEPS + 1, BATCH, …) array} of a seeded reset and STEPS steps."""
    import jax
    import jax.numpy as jnp

    from training import envs
    env = envs.make(task, config_overrides={"backend": "cpu", "episode_length": 50, **overrides})
    reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
    state = reset(jax.random.split(jax.random.PRNGKey(7), BATCH))
    base = np.zeros(env.action_size, np.float32)
    if hold_kneel:
        scale = np.asarray(env.manifest_fields()["action_scale"])
        base = ((np.asarray(env._kneel_qpos[7:]) - np.asarray(env._default_pose)) / scale).astype(np.float32)
    rng = np.random.default_rng(0)
    series: dict[str, list] = {}
    for k in range(STEPS + 1):
        out = {"reward": state.reward, "done": state.done, "obs": state.obs["state"],
               "privileged": state.obs["privileged_state"], "qpos": state.data.qpos,
               **{f"metric:{m}": v for m, v in state.metrics.items()}}
        for name, value in out.items():
            series.setdefault(name, []).append(np.asarray(value))
        if k < STEPS:
            action = base + rng.uniform(-ACTION_NOISE, ACTION_NOISE, (BATCH, env.action_size)).astype(np.float32)
            state = step(state, jnp.asarray(action))
    return {name: np.stack(values) for name, values in series.items()}


@pytest.fixture(scope="module")
def golden():
    with np.load(GOLDEN) as z:
        return {k: z[k] for k in z.files}


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES)
def test_a_getup_task_steps_as_recorded(golden, case):
    fresh = record(*CASES[case])
    stored = {k.split("/", 1)[1]: v for k, v in golden.items() if k.startswith(case + "/")}
    assert set(fresh) == set(stored), f"{case}: series {sorted(set(fresh) ^ set(stored))} differ"
    for name, values in stored.items():
        np.testing.assert_allclose(fresh[name], values, rtol=RTOL, atol=ATOL, err_msg=f"{case}: {name}")


def main(cases: list[str]) -> int:
    unknown = sorted(set(cases) - set(CASES))
    if unknown:
        print(f"test_getup_steps: unknown case {', '.join(unknown)}; cases: {', '.join(CASES)}", file=sys.stderr)
        return 2
    cases = cases or list(CASES)
    with np.load(GOLDEN) as z:
        arrays = {k: z[k] for k in z.files if k.split("/", 1)[0] not in cases}
    arrays.update({f"{case}/{name}": values for case in cases for name, values in record(*CASES[case]).items()})
    np.savez_compressed(GOLDEN, **arrays)
    print(f"{GOLDEN}: {', '.join(cases)} rewritten; {len(arrays)} series")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

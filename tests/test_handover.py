"""Hand-over starts of the joystick expert (training/envs/starts/handover.py): where the stitched teacher hands a
rising robot from the shipped keyframe getup expert to the joystick expert, and the joystick env's resets
from them. The slow tests roll the getup expert (CPU physics) and compile one joystick reset."""
from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from common import model as t1model
from messages import contract
from messages.contract import WAIST_SWITCH_HEIGHT_M
from training import envs
from training.envs.starts import handover, knockdown
from training.envs.starts.bank import place

GETUP = "policies/getup_knockdown/getup_knockdown.safetensors"
BANK_STARTS = 6


def _rotation(quat) -> np.ndarray:
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, np.asarray(quat, np.float64))
    return mat.reshape(3, 3)


def test_place_turns_the_root_and_its_world_velocity_only():
    mj = t1model.load_model()
    qpos = np.array(mj.key("home").qpos, np.float32)
    qpos[3:7] = (np.cos(0.2), np.sin(0.2), 0.0, 0.0)          # rolled 0.4 rad about x
    qvel = np.arange(mj.nv, dtype=np.float32) * 0.1
    yaw = 0.7
    q2, v2 = (np.asarray(x) for x in place(jnp.asarray(qpos), jnp.asarray(qvel), jnp.array([1.5, -2.0]),
                                                     jnp.float32(yaw)))
    turn = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    np.testing.assert_allclose(_rotation(q2[3:7]), turn @ _rotation(qpos[3:7]), atol=1e-6)
    np.testing.assert_allclose(q2[:3], (1.5, -2.0, qpos[2]), atol=1e-6)
    np.testing.assert_allclose(v2[:3], turn @ qvel[:3], atol=1e-6)          # world-frame linear velocity
    np.testing.assert_allclose(v2[3:], qvel[3:], atol=1e-6)                 # body-frame angular velocity, joints
    np.testing.assert_allclose(q2[7:], qpos[7:])


@pytest.mark.parametrize("over, why", [({"handover.prob": 0.5}, "needs handover.getup_policy"),
                                       ({"handover.prob": 1.5, "handover.getup_policy": GETUP}, r"in \[0, 1\]")])
def test_joystick_env_refuses_a_bad_handover_config(over, why):
    with pytest.raises(ValueError, match=why):
        envs.make("joystick", config_overrides=over)


def _group(**fields):
    group = envs.default_config("joystick").handover
    group.update({"bank_starts": BANK_STARTS, **fields})
    return group


@pytest.fixture(scope="module")
def bank():
    return handover.handover_bank(envs.make, _group(getup_policy=GETUP))


def _assert_waist_at_the_switch(states, num_starts):
    mj = t1model.load_model()
    data = mujoco.MjData(mj)
    waist = mj.body("Waist").id
    assert 1 <= states.qpos.shape[0] <= num_starts
    for qpos, qvel, targets in zip(*states):
        data.qpos[:] = qpos
        mujoco.mj_kinematics(mj, data)
        assert WAIST_SWITCH_HEIGHT_M <= data.xpos[waist, 2] < WAIST_SWITCH_HEIGHT_M + 0.1   # the first tick past
        assert np.all(np.isfinite(qvel)) and np.all(np.isfinite(targets))
    assert np.median(states.qvel[:, 2]) > 0.0          # the rise: the trunk still going up


@pytest.mark.slow
def test_bank_holds_the_states_where_the_waist_passes_the_switch(bank):
    _assert_waist_at_the_switch(bank, BANK_STARTS)


# the keyframe chain's members as the campaign keeps them (newest checkpoints)
CAMPAIGN = Path("training/campaigns/getup_keyframe")
CHAIN = {role: str(sorted((CAMPAIGN / stage / "checkpoints").glob("*"))[-1])
         for role, stage in (("roll", "roll_side"), ("rise", "rise_rolled"), ("stand", "stand_still"))}


@pytest.mark.slow
def test_the_keyframe_chain_hands_over_from_its_stand_at_the_switch():
    """With rise_policy set, the bank is the chain's: its stand rolled from the kneels its rise hands over."""
    states = handover.handover_bank(envs.make, _group(getup_policy=CHAIN["stand"], rise_policy=CHAIN["rise"],
                                                      roll_policy=CHAIN["roll"], bank_starts=4))
    _assert_waist_at_the_switch(states, 4)
    # handed over on the way up from the kneel: the trunk already above the kneel gate's height
    assert np.all(states.qpos[:, 2] > contract.KNEEL_GATE_HEIGHT_M)


def test_a_chain_bank_refuses_a_bad_up_error():
    with pytest.raises(ValueError, match="handover.up_error"):
        handover.handover_bank(envs.make, _group(getup_policy=CHAIN["stand"], rise_policy=CHAIN["rise"],
                                                 up_error=2.5))


@pytest.mark.slow
def test_joystick_env_starts_from_the_bank(bank):
    env = envs.make("joystick", config_overrides={"handover.prob": 1.0, "handover.getup_policy": GETUP,
                                                  "handover.bank_starts": BANK_STARTS, "episode_length": 20})
    state = jax.jit(env.reset)(jax.random.PRNGKey(3))
    q = np.asarray(state.data.qpos)
    row = int(np.argmin(np.abs(bank.qpos[:, 7:] - q[7:]).sum(axis=1)))
    np.testing.assert_allclose(q[7:], bank.qpos[row, 7:], atol=1e-6)           # its joints, as handed over
    np.testing.assert_allclose(q[2], bank.qpos[row, 2], atol=1e-6)             # its height
    expected = np.clip((bank.joint_targets[row] - np.asarray(env._default_pose)) / 0.5, -1.0, 1.0)
    np.testing.assert_allclose(np.asarray(state.info["last_act"]), expected, atol=1e-6)


# ------------------------------------------------------------------ knockdown starts (the other hand-over)
JOYSTICK = "policies/joystick/joystick.safetensors"
KNOCK_STARTS = 8


@pytest.mark.parametrize("over, why", [({"knockdown_starts.prob": 0.5}, "needs knockdown_starts.joystick_policy"),
                                       ({"knockdown_starts.prob": -0.1}, r"in \[0, 1\]")])
def test_getup_env_refuses_a_bad_knockdown_config(over, why):
    with pytest.raises(ValueError, match=why):
        envs.make("getup", config_overrides={"fallen.bank_starts": 2, **over})


@pytest.fixture(scope="module")
def knock_bank():
    return knockdown.knockdown_bank(envs.make, JOYSTICK, KNOCK_STARTS,
                                    seed=int(envs.default_config("getup").knockdown_starts.seed))


@pytest.mark.slow
def test_knockdown_bank_holds_the_states_where_the_waist_drops_past_the_switch(knock_bank):
    qpos, qvel = knock_bank
    mj = t1model.load_model()
    data = mujoco.MjData(mj)
    waist = mj.body("Waist").id
    assert 1 <= qpos.shape[0] <= KNOCK_STARTS
    for q in qpos:
        data.qpos[:] = q
        mujoco.mj_kinematics(mj, data)
        assert WAIST_SWITCH_HEIGHT_M - 0.1 < data.xpos[waist, 2] < WAIST_SWITCH_HEIGHT_M   # the first tick below
    assert np.all(np.isfinite(qvel)) and np.median(qvel[:, 2]) < 0.0                  # still falling
    assert np.median(np.hypot(qvel[:, 0], qvel[:, 1])) > 0.5                           # with the push's momentum


@pytest.mark.slow
def test_getup_env_starts_fallen_episodes_from_the_knockdown_bank(knock_bank):
    env = envs.make("getup", config_overrides={
        "start_probs": [1.0, 0.0, 0.0], "fallen.bank_starts": 2, "episode_length": 20, "knockdown_starts.prob": 1.0,
        "knockdown_starts.joystick_policy": JOYSTICK, "knockdown_starts.bank_starts": KNOCK_STARTS})
    state = jax.jit(env.reset)(jax.random.PRNGKey(3))
    q = np.asarray(state.data.qpos)
    assert np.min(np.abs(knock_bank[0] - q).sum(axis=1)) < 1e-5
    assert int(state.info["start_kind"]) == 0                      # counted with the fallen starts


@pytest.mark.slow
def test_evaluate_from_knockdown_landings(knock_bank, tmp_path):
    """`evaluate --starts knockdown`: one episode per landing of the same (cached) bank, counted from the landing;
    the report names the starts and drops the seed's fallen-start figures."""
    from training.evaluation.batch import evaluate
    seed = int(envs.default_config("getup").knockdown_starts.seed)
    report = evaluate(GETUP, tmp_path, seeds=KNOCK_STARTS, seconds=0.2, first_seed=seed, backend="cpu",
                      starts="knockdown", start_joystick=JOYSTICK).read_text()
    landings = knock_bank[0].shape[0]
    assert f"{landings} knockdown landings (of {KNOCK_STARTS} pushed standing starts" in report
    assert "| lay without a rise to the end (share) |" in report and "seed: policy" not in report
    rows = (tmp_path / "per_env.csv").read_text().splitlines()[1:]
    assert [int(r.split(",")[1]) for r in rows] == list(range(landings))


@pytest.mark.parametrize("over, why", [({"starts": "kneeling"}, "starts 'kneeling'"),
                                       ({"starts": "knockdown"}, "start joystick policy goes with"),
                                       ({"start_joystick": JOYSTICK}, "start joystick policy goes with")])
def test_evaluate_refuses_bad_starts(over, why, tmp_path):
    from training.evaluation.batch import evaluate
    with pytest.raises(ValueError, match=why):
        evaluate(GETUP, tmp_path, seeds=1, seconds=0.2, backend="cpu", **over)


def test_evaluate_cli_keeps_the_start_joystick_with_its_starts(capsys):
    from training import cli
    assert cli.main(["evaluate", "--policy", GETUP, "--start-joystick", JOYSTICK]) == 2
    assert "--start-joystick goes with" in capsys.readouterr().err



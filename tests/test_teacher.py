"""The stitched teacher speaks the student's action map: each expert's action becomes the same joint
targets in it (the joystick expert's ±0.5 rad map and the getup expert's wider one differ)."""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from common import observation as obsdef
from training import cli as training_cli
from training.distill.teacher import STUDENT_OBS_KEY, WAIST_OBS_KEY, Expert, make_teacher

N = obsdef.NUM_JOINTS


def _expert(name, terms, scale, bias):
    """A constant policy: zero weights, output bias `bias` (pre-tanh loc)."""
    size = obsdef.observation_size(terms)
    layers = ((np.zeros((2 * N, size), np.float32),
               np.concatenate([np.full(N, bias), np.zeros(N)]).astype(np.float32)),)
    return Expert(name, layers, np.zeros(size, np.float32), np.ones(size, np.float32), "swish", tuple(terms),
                  np.full(N, scale, np.float32))


def test_each_expert_reaches_the_same_targets_in_the_student_map():
    getup = _expert("getup", obsdef.TERMS_GETUP, 2.0, 0.3)
    joystick = _expert("joystick", obsdef.TERMS_UNION, 0.5, 0.3)
    teacher = make_teacher(getup, joystick, obsdef.TERMS_UNION, 2.0)
    action, extra = teacher(_obs())
    action, loc = np.asarray(action), np.asarray(extra["loc"])
    np.testing.assert_allclose(2.0 * action[0], 2.0 * np.tanh(0.3), rtol=1e-6)   # getup: its own map
    np.testing.assert_allclose(2.0 * action[1], 0.5 * np.tanh(0.3), rtol=1e-5)   # joystick: same targets
    np.testing.assert_array_equal(loc, action)                   # the student acts with loc itself
    with pytest.raises(ValueError, match="exceeds the student's"):
        make_teacher(getup, joystick, obsdef.TERMS_UNION, 0.5)


def _obs():
    """Two envs in the student's layout, waist below the switch height in the first, above in the second."""
    obs = jnp.zeros((2, obsdef.observation_size(obsdef.TERMS_UNION)))
    return {STUDENT_OBS_KEY: obs, WAIST_OBS_KEY: jnp.array([[0.2], [0.6]])}


def test_brax_bc_loss_is_least_where_the_student_executes_the_teachers_action():
    """brax bc's loss compares tanh(loc) whatever the output rule. A student without squash (Table 5.2) acts
    with loc, so its minimiser must be the teacher's action itself, also for saturated getup actions."""
    from brax.training.agents.bc.losses import bc_loss
    getup = _expert("getup", obsdef.TERMS_GETUP, 2.0, 1.5)        # tanh(1.5) = 0.905: a large getup target
    joystick = _expert("joystick", obsdef.TERMS_UNION, 0.5, 0.3)
    teacher = make_teacher(getup, joystick, obsdef.TERMS_UNION, 2.0)
    obs = _obs()
    teacher_action, extras = teacher(obs)

    def loss_if_student_executes(executed):
        def make_policy(params):
            return lambda o, key_sample=None: (None, {"loc": executed})   # it acts with loc
        return float(bc_loss(None, None, {"observations": obs, "teacher_action_extras": extras}, make_policy)[0])

    assert loss_if_student_executes(teacher_action) < 1e-8
    for miss in (-0.05, 0.05):
        assert loss_if_student_executes(teacher_action + miss) > 1e-4


def test_each_expert_reads_its_own_previous_action():
    """The env's last action is in the student's map; the joystick expert (±0.5 rad per unit against the
    student's 2) must read it back in its own, clipped to its tanh range, else it sees a quarter of it."""
    at = obsdef.term_slice(obsdef.TERMS_UNION, "last_action")
    size = obsdef.observation_size(obsdef.TERMS_UNION)
    # a linear probe: loc = the last_action entries the joystick expert reads (weights pick that slice)
    probe = np.zeros((2 * N, size), np.float32)
    probe[np.arange(N), np.arange(at.start, at.stop)] = 1.0
    joystick = Expert("joystick", ((probe, np.zeros(2 * N, np.float32)),), np.zeros(size, np.float32),
                      np.ones(size, np.float32), "swish", obsdef.TERMS_UNION, np.full(N, 0.5, np.float32))
    getup = _expert("getup", obsdef.TERMS_GETUP, 2.0, 0.3)     # reads no last action: untouched
    teacher = make_teacher(getup, joystick, obsdef.TERMS_UNION, 2.0)
    last_student = np.zeros((2, N), np.float32)
    last_student[1, :2] = (0.1, 0.6)          # the joystick's own 0.4, and a getup target beyond its range
    obs = _obs()
    obs[STUDENT_OBS_KEY] = obs[STUDENT_OBS_KEY].at[:, at].set(last_student)
    action = np.asarray(teacher(obs)[0])
    read = np.arctanh(action[1, :2] * 4.0)          # back through the joystick's tanh and the map ratio
    np.testing.assert_allclose(read, (0.4, 1.0), rtol=1e-4)
    np.testing.assert_allclose(action[0], np.tanh(0.3), rtol=1e-6)
    assert obsdef.term_slice(obsdef.TERMS_GETUP, "last_action") is None


def test_the_chain_teacher_acts_with_the_stage_s_member():
    """The keyframe chain (roll, rise, stand): the member the stage in the observation names acts."""
    from training.distill.teacher import STAGE_OBS_KEY, make_chain_teacher
    members = [_expert(name, obsdef.TERMS_GETUP, 2.0, bias) for name, bias in (("roll", 0.1), ("rise", 0.2),
                                                                                ("stand", 0.3))]
    teacher = make_chain_teacher(members, obsdef.TERMS_GETUP, 2.0)
    obs = {STUDENT_OBS_KEY: jnp.zeros((3, obsdef.observation_size(obsdef.TERMS_GETUP))),
           STAGE_OBS_KEY: jnp.array([[2.0], [0.0], [1.0]])}
    action, extra = teacher(obs)
    np.testing.assert_allclose(np.asarray(action)[:, 0], np.tanh([0.3, 0.1, 0.2]), rtol=1e-6)
    np.testing.assert_allclose(np.asarray(extra["loc"]), np.asarray(action), rtol=1e-6)
    with pytest.raises(ValueError, match="a chain teacher has 3 members"):
        make_chain_teacher(members[:2], obsdef.TERMS_GETUP, 2.0)


def test_the_kneeling_teacher_is_the_chain_below_the_waist_switch_and_the_joystick_above():
    """Roll, rise, stand by the stage while the waist is below 0.5 m; the joystick expert at or above it, whatever
    the stage; the stage and waist wrappers compose for the DAgger env."""
    from training.distill.teacher import KNEELING, STAGE_OBS_KEY, WAIST_OBS_KEY, make_kneeling_teacher, teacher_kind
    members = [_expert(name, obsdef.TERMS_UNION, 2.0, bias) for name, bias in (("roll", 0.1), ("rise", 0.2),
                                                                                ("stand", 0.3), ("joystick", 0.4))]
    teacher = make_kneeling_teacher(members, obsdef.TERMS_UNION, 2.0)
    obs = {STUDENT_OBS_KEY: jnp.zeros((3, obsdef.observation_size(obsdef.TERMS_UNION))),
           STAGE_OBS_KEY: jnp.array([[1.0], [2.0], [2.0]]), WAIST_OBS_KEY: jnp.array([[0.3], [0.49], [0.5]])}
    action, _ = teacher(obs)
    np.testing.assert_allclose(np.asarray(action)[:, 0], np.tanh([0.2, 0.3, 0.4]), rtol=1e-6)
    assert teacher_kind({r: "x" for r in ("joystick", "stand", "rise", "roll")}) == KNEELING
    with pytest.raises(ValueError, match="a kneeling teacher has 4 members"):
        make_kneeling_teacher(members[:3], obsdef.TERMS_UNION, 2.0)


def test_distill_names_a_bad_teacher(capsys):
    assert training_cli.main(["distill", "--getup", "g", "--out", "o"]) == 2
    assert "needs both --getup and --joystick" in capsys.readouterr().err
    assert training_cli.main(["distill", "--chain", "a,b", "--out", "o"]) == 2
    assert "--chain takes 3 artifacts" in capsys.readouterr().err
    assert training_cli.main(["distill", "--chain", "a,b,c", "--getup", "g", "--out", "o"]) == 2
    assert "either --getup and --joystick" in capsys.readouterr().err

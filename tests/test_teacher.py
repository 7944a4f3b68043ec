"""The stitched teacher speaks the student's action map: each expert's action becomes the same joint
targets in it (the joystick expert's ±0.5 rad map and the getup expert's wider one differ)."""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from training import observation as obsdef
from training.teacher import STUDENT_OBS_KEY, WAIST_OBS_KEY, Expert, make_teacher

N = obsdef.NUM_JOINTS


def _expert(name, terms, scale, bias):
    """A constant policy: zero weights, output bias `bias` (pre-tanh loc)."""
    size = obsdef.observation_size(terms)
    layers = ((np.zeros((2 * N, size), np.float32), np.concatenate([np.full(N, bias), np.zeros(N)]).astype(np.float32)),)
    return Expert(name, layers, np.zeros(size, np.float32), np.ones(size, np.float32), "swish", tuple(terms),
                  np.full(N, scale, np.float32))


def test_each_expert_reaches_the_same_targets_in_the_student_map():
    getup = _expert("getup", obsdef.TERMS_GETUP, 2.0, 0.3)
    joystick = _expert("joystick", obsdef.TERMS_UNION, 0.5, 0.3)
    teacher = make_teacher(getup, joystick, obsdef.TERMS_UNION, 2.0)
    obs = jnp.zeros((2, obsdef.observation_size(obsdef.TERMS_UNION)))
    action, extra = teacher({STUDENT_OBS_KEY: obs, WAIST_OBS_KEY: jnp.array([[0.2], [0.6]])})
    action, loc = np.asarray(action), np.asarray(extra["loc"])
    np.testing.assert_allclose(2.0 * action[0], 2.0 * np.tanh(0.3), rtol=1e-6)   # getup: its own map
    np.testing.assert_allclose(2.0 * action[1], 0.5 * np.tanh(0.3), rtol=1e-5)   # joystick: same targets
    np.testing.assert_allclose(np.tanh(loc), action, rtol=1e-5)
    with pytest.raises(ValueError, match="exceeds the student's"):
        make_teacher(getup, joystick, obsdef.TERMS_UNION, 0.5)

"""Joystick reward terms (training/envs/joystick_rewards.py) where they depart from a plain restatement."""
import jax.numpy as jnp
import numpy as np

from common import observation as obsdef
from training.envs import joystick_rewards as R

SWING_HEIGHT_M = 0.08
FREEZE_NORM = 0.01
# the clock frozen at the episode's initial phase (0, −π): the left foot's reference is at its swing peak
FROZEN_PHASE = obsdef.initial_gait_phase(jnp)


def test_zero_command_rewards_both_feet_on_the_floor_whatever_the_frozen_clock():
    still = jnp.zeros(3)
    on_floor = R.feet_phase(jnp.zeros(2), FROZEN_PHASE, SWING_HEIGHT_M, still, FREEZE_NORM)
    one_foot_up = R.feet_phase(jnp.array([SWING_HEIGHT_M, 0.0]), FROZEN_PHASE, SWING_HEIGHT_M, still, FREEZE_NORM)
    assert np.isclose(float(on_floor), 1.0) and float(one_foot_up) < 0.6


def test_a_moving_command_tracks_the_clocks_swing_reference():
    walk = jnp.array([0.4, 0.0, 0.0])
    peak_left = R.feet_phase(jnp.array([SWING_HEIGHT_M, 0.0]), FROZEN_PHASE, SWING_HEIGHT_M, walk, FREEZE_NORM)
    flat = R.feet_phase(jnp.zeros(2), FROZEN_PHASE, SWING_HEIGHT_M, walk, FREEZE_NORM)
    assert np.isclose(float(peak_left), 1.0) and float(flat) < float(peak_left)

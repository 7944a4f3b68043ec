"""What every start bank shares: rows frozen for caching, and a robot's state moved about the floor."""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from brax import math as brax_math


def frozen_bank(pick, qpos: np.ndarray, qvel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A bank's (qpos, qvel) rows `pick` (a mask or indices), float32 and read-only (banks are cached and shared)."""
    bank = qpos[pick].astype(np.float32), qvel[pick].astype(np.float32)
    for array in bank:
        array.flags.writeable = False
    return bank


def place(qpos, qvel, xy, yaw):
    """A free-floating robot's state moved to `xy` [m] and turned by `yaw` [rad] about the world z axis:
    the root orientation and the world-frame linear velocity turn; the body-frame angular velocity and the
    joints do not."""
    turn = brax_math.quat_rot_axis(jnp.array([0.0, 0.0, 1.0]), yaw)     # (w, x, y, z), as MuJoCo's
    qpos = qpos.at[0:2].set(xy).at[3:7].set(brax_math.quat_mul(turn, qpos[3:7]))
    return qpos, qvel.at[0:3].set(brax_math.rotate(qvel[0:3], turn))

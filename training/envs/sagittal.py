"""A sagittal, left-right mirrored action space (FRASA's reduced getup; ours: the kneel task's backplay uses it).

The policy sets the pitch joints only, one value per left/right pair; every roll and yaw joint (head yaw,
shoulder and hip roll, elbow and hip yaw, the waist, ankle roll) keeps its home target (action 0). Why: the kneel
differs from home in hip, knee and ankle pitch only, and both sides' pitch joints share one axis, so mirroring is a
copy; over all 23 joints the learner sprawls from the planner's arrivals and lets the trunk sag below the gate
(training/LESSONS.md). The env expands the action before anything reads it (base.T1Env.full_action), so
observations (last_action), targets and artifacts stay in the 23-joint contract.
"""
from __future__ import annotations

import numpy as np

from messages.contract import JOINT_NAMES, NUM_JOINTS

# the reduced action's entries, each the joint of that name (the head) or both sides' (Left_/Right_ + name)
PITCH_JOINTS = ("Head_pitch", "Shoulder_Pitch", "Elbow_Pitch", "Hip_Pitch", "Knee_Pitch", "Ankle_Pitch")
ACTION_SPACES = ("full", "sagittal")


def expansion() -> np.ndarray:
    """(23, len(PITCH_JOINTS)) 0/1 matrix: full action = matrix @ reduced action."""
    m = np.zeros((NUM_JOINTS, len(PITCH_JOINTS)), np.float32)
    for j, name in enumerate(PITCH_JOINTS):
        rows = [i for i, n in enumerate(JOINT_NAMES) if n == name or n in (f"Left_{name}", f"Right_{name}")]
        if len(rows) not in (1, 2):
            raise ValueError(f"sagittal: joint {name!r} matches {len(rows)} contract joints")
        m[rows, j] = 1.0
    return m


def action_size(space: str) -> int:
    """The policy's action size in an action space."""
    if space not in ACTION_SPACES:
        raise ValueError(f"action_space {space!r} unknown; valid: {', '.join(ACTION_SPACES)}")
    return NUM_JOINTS if space == "full" else len(PITCH_JOINTS)


def expand_policy(policy_params) -> dict:
    """A sagittal policy's brax tanh-normal params → the same policy over the 23 joints (what artifacts and the
    runtime hold): the output layer's loc and scale columns copied to every joint their pitch value drives;
    tanh commutes with the copy, so the artifact's actions are the env's expanded ones. Held joints get zero
    columns (loc 0: home)."""
    inner = dict(policy_params.get("params", policy_params))
    last = f"hidden_{len(inner) - 1}"
    kernel, bias = np.asarray(inner[last]["kernel"]), np.asarray(inner[last]["bias"])
    n = len(PITCH_JOINTS)
    if kernel.shape[-1] != 2 * n:
        raise ValueError(f"sagittal: the policy's output layer has {kernel.shape[-1]} outputs, a sagittal "
                         f"tanh-normal policy has {2 * n} (loc and scale of {n} pitch values)")
    e = expansion().T                                   # (n, 23)
    inner[last] = {"kernel": np.concatenate([kernel[:, :n] @ e, kernel[:, n:] @ e], axis=1),
                   "bias": np.concatenate([bias[:n] @ e, bias[n:] @ e])}
    return {"params": inner}

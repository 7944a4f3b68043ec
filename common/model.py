"""The project's Booster T1 MuJoCo model: loading, keyframes, the shared PD gain set, spawn states.

Everything that needs the robot model (HIL simulator, MJX envs, tests) goes through this module, so the
joint order and ranges (messages/contract.json), the gains (custom numerics in t1.xml) and the spawn states
are the same everywhere.
"""
from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from common.events import forward_z_from_quat
from messages import contract

MODEL_PATH: Path = Path(__file__).resolve().parent / "models" / "t1.xml"

NUM_JOINTS = contract.NUM_JOINTS
ROOT_QPOS = 7  # free joint: 3 position + 4 quaternion (w x y z)
ROOT_QVEL = 6  # free joint: 3 linear + 3 angular velocity

# MJX buffer sizes for ONE world of this model (training code passes them to mjx.make_data; batched
# warp backends multiply naconmax by the batch size). Measured in C MuJoCo over 64 fallen seeds: settled
# max 7 contacts / 51 constraint rows (median 4 / 40), max 14 / 80 during the drops themselves; home 8 /
# 55, kneel 6 / 47 (tests/test_model.py asserts the settled ones fit). 32 contacts leave room for
# thrashing getup attempts and for walls / puddles. Rows: frictionloss gives 23 rows always, joint
# limits up to 23, each pyramidal condim-3 contact 4.
MJX_NCONMAX = 32
MJX_NJMAX = 2 * NUM_JOINTS + 4 * MJX_NCONMAX  # 174

# fallen-state generator (seeded drop from random pose) -----------------------------------------------
FALL_ROOT_HEIGHT_M = (0.5, 0.7)   # root drop height range [m]
FALL_MIN_CLEARANCE_M = 0.02       # lowest geom starts at least this far above the floor [m]
FALL_SETTLE_S = 0.5               # minimum simulated time after the first ground contact [s]
# ... then the drop goes on until the robot is at rest: 0.5 s after contact most drops still roll
# (measured: root speeds up to 0.5 m/s and 2 rad/s after 1 s; < 0.03 m/s after 2 s).
FALL_REST_LINVEL_MPS = 0.05       # root linear speed, each axis [m/s]
FALL_REST_ANGVEL_RADPS = 0.2      # root angular speed, each axis [rad/s]
FALL_REST_JOINTVEL_RADPS = 1.0    # joint speed [rad/s]
FALL_MAX_S = 4.0                  # hard cap on the simulated time of one drop [s]
FALL_MAX_TRIES = 200              # resamples of a self-colliding random pose before giving up

SPAWNS = ("standing", "kneeling", "fallen")


def _joint_ids(model: mujoco.MjModel) -> np.ndarray:
    """MuJoCo joint ids in the contract order; raises if the model does not match the contract."""
    ids = []
    for i, name in enumerate(contract.JOINT_NAMES):
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0:
            raise ValueError(f"model has no joint named {name!r} (contract joint {i})")
        if model.jnt_qposadr[jid] != ROOT_QPOS + i or model.jnt_dofadr[jid] != ROOT_QVEL + i:
            raise ValueError(f"joint {name!r} is not at qpos {ROOT_QPOS + i} / qvel {ROOT_QVEL + i}")
        ids.append(jid)
    return np.array(ids)


def _actuator_ids(model: mujoco.MjModel) -> np.ndarray:
    ids = []
    for i, name in enumerate(contract.JOINT_NAMES):
        aid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
        if aid != i:
            raise ValueError(f"actuator {name!r} must be actuator {i} (found id {aid})")
        ids.append(aid)
    return np.array(ids)


def robot_spec() -> mujoco.MjSpec:
    """The robot file (robot + floor) as an MjSpec, with each joint's range from the contract (t1.xml leaves
    them out: the contract is the one source for the model and the motors' soft stops)."""
    spec = mujoco.MjSpec.from_file(str(MODEL_PATH))
    for name, (lo, hi) in zip(contract.JOINT_NAMES, contract.JOINT_RANGES_RAD):
        joint = spec.joint(name)
        if joint is None:
            raise ValueError(f"{MODEL_PATH}: no joint {name!r} (messages/contract.json names it)")
        joint.range = [lo, hi]
        joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
    return spec


def load_model() -> mujoco.MjModel:
    """The bare robot model (robot + floor), without any scenario."""
    return robot_spec().compile()


def keyframe_qpos(model: mujoco.MjModel, name: str) -> np.ndarray:
    kid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, name)
    if kid < 0:
        raise ValueError(f"model has no keyframe {name!r}")
    return model.key_qpos[kid].copy()


def default_pose(model: mujoco.MjModel) -> np.ndarray:
    """The 23 joint angles of the `home` keyframe [rad], contract order."""
    _joint_ids(model)
    return keyframe_qpos(model, "home")[ROOT_QPOS:ROOT_QPOS + NUM_JOINTS]


def kneel_pose(model: mujoco.MjModel) -> np.ndarray:
    """The 23 joint angles of the `kneel` keyframe [rad], contract order."""
    _joint_ids(model)
    return keyframe_qpos(model, "kneel")[ROOT_QPOS:ROOT_QPOS + NUM_JOINTS]


def _numeric(model: mujoco.MjModel, name: str) -> np.ndarray:
    nid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_NUMERIC, name)
    if nid < 0:
        raise ValueError(f"model has no custom numeric {name!r}")
    adr, size = model.numeric_adr[nid], model.numeric_size[nid]
    if size != NUM_JOINTS:
        raise ValueError(f"custom numeric {name!r} has {size} values, expected {NUM_JOINTS}")
    return model.numeric_data[adr:adr + size].copy()


def pd_gains(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """The shared gain set: (kp [N·m/rad], kd [N·m·s/rad]), 23 each, contract order."""
    return _numeric(model, "pd_kp"), _numeric(model, "pd_kd")


def torque_limits(model: mujoco.MjModel) -> np.ndarray:
    """Motor torque limits [N·m] (the symmetric actuator ctrlrange), contract order."""
    ids = _actuator_ids(model)
    return model.actuator_ctrlrange[ids, 1].copy()


def joint_ranges(model: mujoco.MjModel) -> np.ndarray:
    """Joint position limits, shape (23, 2) [rad], contract order."""
    return model.jnt_range[_joint_ids(model)].copy()


def pd_torque(q_des, q, dq, kp, kd, tau_limit) -> np.ndarray:
    """Motor PD law, same formula and clamp as firmware_like: clip(kp·(q_des − q) − kd·dq, ±limit)."""
    return np.clip(kp * (q_des - q) - kd * dq, -tau_limit, tau_limit)


def trunk_height(data: mujoco.MjData) -> float:
    """Trunk (root, IMU) body origin height [m]."""
    return float(data.xpos[data.model.body("Trunk").id, 2])


def trunk_heights(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """Trunk origin heights [m] of a batch of states qpos [N, nq] (kinematics only)."""
    data = mujoco.MjData(model)
    heights = []
    for q in qpos:
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        heights.append(trunk_height(data))
    return np.array(heights)


def trunk_forward_z(qpos: np.ndarray) -> np.ndarray:
    """World z of the trunk's forward (x) axis for states qpos [..., nq], from the free joint's quaternion:
    near -1 lying face down, near +1 on the back."""
    return forward_z_from_quat(np.asarray(qpos)[..., 3:ROOT_QPOS])


def waist_height(data: mujoco.MjData) -> float:
    """Waist (pelvis) body origin height [m]."""
    return float(data.xpos[data.model.body("Waist").id, 2])


def robot_geom_mask(model: mujoco.MjModel) -> np.ndarray:
    """True for geoms on the robot (not on the world body: floor, walls, puddles)."""
    return model.geom_bodyid != 0


def ground_contacts(model: mujoco.MjModel, data: mujoco.MjData) -> list[int]:
    """Robot geom ids touching any world geom (floor, wall, puddle)."""
    robot = robot_geom_mask(model)
    out = []
    for c in data.contact[:data.ncon]:
        if robot[c.geom1] != robot[c.geom2]:
            out.append(int(c.geom1 if robot[c.geom1] else c.geom2))
    return out


def self_contacts(model: mujoco.MjModel, data: mujoco.MjData) -> list[tuple[str, str]]:
    """Robot-robot contacts as geom-name pairs."""
    robot = robot_geom_mask(model)
    return [(model.geom(c.geom1).name, model.geom(c.geom2).name)
            for c in data.contact[:data.ncon] if robot[c.geom1] and robot[c.geom2]]


def lowest_robot_point(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """Lowest z of any robot collision primitive [m] (after mj_kinematics / mj_forward)."""
    lowest = np.inf
    for g in np.flatnonzero(robot_geom_mask(model)):
        centre, rot, size = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3), model.geom_size[g]
        gtype = model.geom_type[g]
        if gtype == mujoco.mjtGeom.mjGEOM_SPHERE:
            z = centre[2] - size[0]
        elif gtype == mujoco.mjtGeom.mjGEOM_CAPSULE:
            z = centre[2] - abs(rot[2, 2]) * size[1] - size[0]
        elif gtype == mujoco.mjtGeom.mjGEOM_BOX:
            z = centre[2] - np.abs(rot[2, :]) @ size[:3]
        else:
            raise ValueError(f"unexpected robot geom type {gtype} for geom {model.geom(g).name!r}")
        lowest = min(lowest, z)
    return float(lowest)


def _random_quat(rng: np.random.Generator) -> np.ndarray:
    """Uniformly random orientation (normalised 4-D Gaussian), w >= 0."""
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def _at_rest(qvel: np.ndarray) -> bool:
    return bool(np.all(np.abs(qvel[0:3]) < FALL_REST_LINVEL_MPS)
                and np.all(np.abs(qvel[3:6]) < FALL_REST_ANGVEL_RADPS)
                and np.all(np.abs(qvel[ROOT_QVEL:]) < FALL_REST_JOINTVEL_RADPS))


def fallen_state(model: mujoco.MjModel, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A settled lying state, deterministic for `seed`.

    Drop from a root height U(0.5, 0.7) m with a uniformly random orientation and joint angles uniform
    within the joint ranges (poses in self-contact are resampled from the same generator). Where that
    pose would start inside the floor, the root is raised until the lowest primitive is
    FALL_MIN_CLEARANCE_M above it. The joints are held toward the random angles by the shared PD gains
    (torques clamped to the motor limits) while the robot falls; the state FALL_SETTLE_S after the
    first ground contact and at rest (FALL_REST_* thresholds) is returned; FALL_MAX_S caps the drop.
    """
    rng = np.random.default_rng(seed)
    data = mujoco.MjData(model)
    ranges = joint_ranges(model)
    kp, kd = pd_gains(model)
    tau_limit = torque_limits(model)
    joints = slice(ROOT_QPOS, ROOT_QPOS + NUM_JOINTS)
    dofs = slice(ROOT_QVEL, ROOT_QVEL + NUM_JOINTS)

    for _ in range(FALL_MAX_TRIES):
        mujoco.mj_resetData(model, data)
        data.qpos[2] = rng.uniform(*FALL_ROOT_HEIGHT_M)
        data.qpos[3:7] = _random_quat(rng)
        data.qpos[joints] = rng.uniform(ranges[:, 0], ranges[:, 1])
        mujoco.mj_forward(model, data)
        if not self_contacts(model, data):
            break
    else:
        raise RuntimeError(f"fallen_state(seed={seed}): no self-contact-free pose in {FALL_MAX_TRIES} tries")

    clearance = lowest_robot_point(model, data)
    if clearance < FALL_MIN_CLEARANCE_M:
        data.qpos[2] += FALL_MIN_CLEARANCE_M - clearance
        mujoco.mj_forward(model, data)
    q_target = data.qpos[joints].copy()

    max_steps = int(round(FALL_MAX_S / model.opt.timestep))
    settle_steps = int(round(FALL_SETTLE_S / model.opt.timestep))
    steps_left = None
    for _ in range(max_steps):
        data.ctrl[:] = pd_torque(q_target, data.qpos[joints], data.qvel[dofs], kp, kd, tau_limit)
        mujoco.mj_step(model, data)
        if steps_left is None and ground_contacts(model, data):
            steps_left = settle_steps
        if steps_left is not None:
            steps_left -= 1
            if steps_left <= 0 and _at_rest(data.qvel):
                break
    return data.qpos.copy(), data.qvel.copy()


def spawn_state(model: mujoco.MjModel, spawn: str, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Initial (qpos, qvel): "standing" = home, "kneeling" = kneel, "fallen" = fallen_state(seed)."""
    if spawn == "standing":
        return keyframe_qpos(model, "home"), np.zeros(model.nv)
    if spawn == "kneeling":
        return keyframe_qpos(model, "kneel"), np.zeros(model.nv)
    if spawn == "fallen":
        return fallen_state(model, seed)
    raise ValueError(f"unknown spawn {spawn!r}; valid: {', '.join(SPAWNS)}")

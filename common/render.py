"""Offscreen frames of the robot from qpos, seen by a camera that tracks the Trunk: for the simulator's
videos (sim_hil/recorder.py) and training's figures (start paths, frame strips). MUJOCO_GL=osmesa on a
headless machine, egl on a GPU."""
from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "osmesa")        # before mujoco loads: it picks its GL platform on import
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])

import mujoco  # noqa: E402


def tracking_camera(model: mujoco.MjModel) -> mujoco.MjvCamera:
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_TRACKING
    camera.trackbodyid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "Trunk")
    camera.distance, camera.elevation, camera.azimuth = 2.8, -15.0, 135.0
    return camera


def render_frames(model: mujoco.MjModel, poses, camera: mujoco.MjvCamera, height: int, width: int) -> list:
    """One RGB frame (height, width, 3) per qpos in `poses`, seen through `camera`."""
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    data = mujoco.MjData(model)
    renderer = mujoco.Renderer(model, height=height, width=width)
    try:
        frames = []
        for qpos in poses:
            data.qpos[:] = qpos
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)      # subtree_com: the tracking camera looks at the Trunk's
            renderer.update_scene(data, camera)
            frames.append(renderer.render())
        return frames
    finally:
        renderer.close()


def save_side_strip(model: mujoco.MjModel, poses, out_png: str, lookat_m, elevation_deg: float, px: int) -> None:
    """The poses seen from the robot's left side (2 m away, looking at lookat_m [m]), left to right, as one PNG."""
    import numpy as np
    import PIL.Image
    camera = mujoco.MjvCamera()
    camera.lookat[:], camera.distance, camera.elevation, camera.azimuth = lookat_m, 2.0, elevation_deg, 90.0
    strip = np.concatenate(render_frames(model, poses, camera, px, px), axis=1)
    PIL.Image.fromarray(strip).save(out_png, optimize=True)

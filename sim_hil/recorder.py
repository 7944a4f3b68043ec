"""Offscreen video of a run: a camera that follows the Trunk, frames at VIDEO_FPS of sim time, mp4 at the end.
Uses MuJoCo's renderer (MUJOCO_GL=osmesa on a headless machine, egl on a GPU) and mediapy/ffmpeg."""
from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np

from sim_hil import config

os.environ.setdefault("MUJOCO_GL", "osmesa")
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])


class Recorder:
    def __init__(self, model: mujoco.MjModel, path: str, fps: int = config.VIDEO_FPS):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.fps = fps
        height, width = config.VIDEO_SIZE
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
        model.vis.global_.offheight = max(model.vis.global_.offheight, height)
        self.renderer = mujoco.Renderer(model, height=height, width=width)
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        self.camera.trackbodyid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "Trunk")
        self.camera.distance, self.camera.elevation, self.camera.azimuth = 2.5, -15.0, 135.0
        self.frames: list[np.ndarray] = []
        self._next_t = 0.0

    def maybe_capture(self, data: mujoco.MjData) -> None:
        if data.time + 1e-9 < self._next_t:
            return
        self._next_t += 1.0 / self.fps
        self.renderer.update_scene(data, self.camera)
        self.frames.append(self.renderer.render())

    def close(self) -> None:
        import mediapy
        if self.frames:
            mediapy.write_video(str(self.path), self.frames, fps=self.fps)
        self.renderer.close()

"""Offscreen video of a run: a camera that follows the Trunk. During the run only the pose (qpos) is kept
at VIDEO_FPS of sim time, so recording never slows realtime pacing (software GL renders a frame in tens of
ms); the frames are rendered and encoded to mp4 when the run ends. MUJOCO_GL=osmesa on a headless machine,
egl on a GPU."""
from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np

from common.render import render_frames, tracking_camera
from sim_hil import config


def render_video(model: mujoco.MjModel, poses: list[np.ndarray], path: Path, fps: int) -> None:
    import mediapy
    height, width = config.VIDEO_SIZE
    mediapy.write_video(str(path), render_frames(model, poses, tracking_camera(model), height, width), fps=fps)


def check_gl_backend(model: mujoco.MjModel) -> None:
    """--record renders when the run ends: make sure it can, before the run starts (RuntimeError if not)."""
    try:
        import mediapy  # noqa: F401
        mujoco.Renderer(model, height=config.GL_PROBE_SIZE_PX, width=config.GL_PROBE_SIZE_PX).close()
    except Exception as exc:  # mujoco raises FatalError/RuntimeError/ImportError depending on the backend
        raise RuntimeError(f"--record: cannot render offscreen with MUJOCO_GL={os.environ.get('MUJOCO_GL')!r} "
                           f"({type(exc).__name__}: {str(exc).strip()[:200]}); install/choose a GL backend "
                           "(osmesa on a headless machine, egl with a GPU) or leave out --record") from None


class Recorder:
    def __init__(self, model: mujoco.MjModel, path: str, fps: int = config.VIDEO_FPS):
        check_gl_backend(model)
        self.model, self.path, self.fps = model, Path(path), fps
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.poses: list[np.ndarray] = []
        self._next_t = 0.0

    def maybe_capture(self, data: mujoco.MjData) -> None:
        if data.time + 1e-9 >= self._next_t:
            self._next_t += 1.0 / self.fps
            self.poses.append(data.qpos.copy())

    def close(self) -> None:
        if self.poses:
            render_video(self.model, self.poses, self.path, self.fps)

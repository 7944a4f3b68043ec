"""Offscreen video of a run: a camera that follows the Trunk, and a caption of what the robot's controller
says (time, the runtime's mode and fault, the joystick command: sim_hil/runtime_view.py), so a fault is seen
in the video, not only printed. During the run only the pose (qpos) and the caption are kept at VIDEO_FPS of
sim time, so recording never slows realtime pacing (software GL renders a frame in tens of ms); the frames
are rendered, captioned and encoded to mp4 when the run ends. MUJOCO_GL=osmesa on a headless machine, egl
on a GPU."""
from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np

from common.render import render_frames, tracking_camera
from sim_hil import config


def caption_frame(frame: np.ndarray, text: str) -> np.ndarray:
    """The frame with `text` on a dark band across its top (a FAULT in red)."""
    import textwrap

    import PIL.Image
    import PIL.ImageDraw
    text = "\n".join(textwrap.fill(line, config.CAPTION_WRAP_CHARS) for line in text.splitlines())
    image = PIL.Image.fromarray(frame)
    draw = PIL.ImageDraw.Draw(image)
    band = draw.multiline_textbbox((config.CAPTION_MARGIN_PX,) * 2, text)[3] + config.CAPTION_MARGIN_PX
    draw.rectangle((0, 0, image.width, band), fill=(0, 0, 0))
    colour = (255, 80, 80) if "FAULT" in text else (255, 255, 255)
    draw.multiline_text((config.CAPTION_MARGIN_PX,) * 2, text, fill=colour)
    return np.asarray(image)


def render_video(model: mujoco.MjModel, poses: list[np.ndarray], path: Path, fps: int,
                 captions: list[str] | None = None) -> None:
    import mediapy
    height, width = config.VIDEO_SIZE
    frames = render_frames(model, poses, tracking_camera(model), height, width)
    if captions is not None:
        frames = [caption_frame(f, c) for f, c in zip(frames, captions)]
    mediapy.write_video(str(path), frames, fps=fps)


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
    """caption: sim time [s] -> the frame's caption text (None: no caption)."""

    def __init__(self, model: mujoco.MjModel, path: str, fps: int = config.VIDEO_FPS, caption=None):
        check_gl_backend(model)
        self.model, self.path, self.fps, self.caption = model, Path(path), fps, caption
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.poses: list[np.ndarray] = []
        self.captions: list[str] = []
        self._next_t = 0.0

    def maybe_capture(self, data: mujoco.MjData) -> None:
        if data.time + 1e-9 >= self._next_t:
            self._next_t += 1.0 / self.fps
            self.poses.append(data.qpos.copy())
            if self.caption is not None:
                self.captions.append(self.caption(data.time))

    def close(self) -> None:
        if self.poses:
            render_video(self.model, self.poses, self.path, self.fps, self.captions if self.caption else None)

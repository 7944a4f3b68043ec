"""The video's tracking camera follows the robot wherever it walks (sim_hil/recorder.py)."""
import numpy as np

from common import model as t1
from sim_hil.recorder import render_frames, tracking_camera

FRAME_PX = 32
WALKED_M = 5.0   # further than the camera's 2.8 m distance: a fixed view would lose the robot
LOOKAT_TOL_M = 0.3


def test_tracking_camera_keeps_looking_at_the_robot():
    model = t1.load_model()
    walked = t1.keyframe_qpos(model, "home")
    walked[:2] += (WALKED_M, -WALKED_M)
    camera = tracking_camera(model)
    render_frames(model, [walked], camera, FRAME_PX, FRAME_PX)   # updates the camera's lookat in place
    assert np.allclose(camera.lookat[:2], walked[:2], atol=LOOKAT_TOL_M), camera.lookat

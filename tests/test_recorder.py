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


def test_a_caption_sits_on_a_band_at_the_top_and_a_fault_shows_in_red():
    from sim_hil.recorder import caption_frame
    frame = np.full((120, 160, 3), 90, np.uint8)
    ok = caption_frame(frame, "t 1.00 s  POLICY\ncommand vx +0.40 vy +0.00 m/s, yaw +0.00 rad/s")
    fault = caption_frame(frame, "t 7.80 s  FAULT (motor 21 (Right_Ankle_Pitch) encoder frozen: q bit-identical "
                                 "for 41 replies under |PD torque| > 10.0 N*m while the body turned)\n"
                                 "command vx +0.40 vy +0.00 m/s, yaw +0.00 rad/s")
    assert np.array_equal(ok[60:], frame[60:]) and not np.array_equal(ok[:20], frame[:20])
    red = lambda img: ((img[..., 0] > 200) & (img[..., 1] < 120)).sum()   # noqa: E731
    assert red(fault) > 0 and red(ok) == 0
    band = lambda img: (img != 90).any(axis=2).any(axis=1).sum()   # noqa: E731  rows the caption covers
    assert band(fault) > band(ok)                                   # the long fault line wraps

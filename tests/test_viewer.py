"""Issue 50 item 1: `python -m sim_hil --viewer` shows the running robot in MuJoCo's viewer; without a
display it says so and the run completes headless."""
import os
import shutil
import subprocess
import sys
import time

import numpy as np
import pytest

from sim_hil.launch import ROOT, _env


def _sim(env, *args):
    return subprocess.Popen([sys.executable, "-m", "sim_hil", "--quiet", "--no-log", "--clock", "realtime", *args],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_viewer_without_a_display_says_so_and_runs_headless(netns):
    env = {k: v for k, v in _env().items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    proc = _sim(env, "--viewer", "--duration", "0.2")
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert "--viewer: no display" in err and "headless" in err and "Traceback" not in err, err


@pytest.mark.skipif(shutil.which("xvfb-run") is None or shutil.which("Xvfb") is None,
                    reason="needs xvfb-run and Xvfb (apt install xvfb) for a virtual display")
def test_viewer_window_shows_the_robot(netns, tmp_path):
    # The test runs itself under Xvfb, so it can grab the screen while the sim runs.
    script = tmp_path / "shot.py"
    script.write_text(f"""
import os, subprocess, sys, time
import numpy as np
from PIL import ImageGrab
proc = subprocess.Popen([sys.executable, "-m", "sim_hil", "--quiet", "--no-log", "--clock", "realtime", "--viewer",
                         "--duration", "0.3"], cwd={str(ROOT)!r}, stderr=subprocess.PIPE, text=True)
best = None
while proc.poll() is None:
    time.sleep(0.5)
    img = np.asarray(ImageGrab.grab(xdisplay=os.environ["DISPLAY"]).convert("RGB"))
    if best is None or img.std() > best.std():
        best = img
err = proc.communicate()[1]
np.save({str(tmp_path / 'shot.npy')!r}, best)
sys.stderr.write(err)
sys.exit(proc.returncode)
""")
    proc = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 640x480x24", sys.executable, str(script)],
                          env=_env(), capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and "Traceback" not in proc.stderr and "no display" not in proc.stderr, proc.stderr
    img = np.load(tmp_path / "shot.npy")
    assert img.std() > 10, "the screen is uniform: no viewer window"
    # The robot is grey in a blue-grey scene with a checker floor: the window holds near-neutral grey
    # pixels (the robot's body) and bluish ones (sky/floor).
    r, g, b = (img[..., i].astype(int) for i in range(3))
    neutral = (abs(r - g) < 8) & (abs(g - b) < 8) & (r > 40) & (r < 200)
    assert neutral.sum() > 500, "no robot-coloured pixels in the viewer window"

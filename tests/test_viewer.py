"""Issue 50 item 1: `python -m sim_hil --viewer` shows the running robot in MuJoCo's viewer; without a
display it says so and the run completes headless."""
import json
import shutil
import subprocess
import sys

import numpy as np
import pytest

from sim_hil.launch import ROOT, _env

DRAG_Y_M = 0.3      # how far sideways the test's perturbation pulls the trunk [m]


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
                         "--duration", "1.5"], cwd={str(ROOT)!r}, stderr=subprocess.PIPE, text=True)
best = None
while proc.poll() is None:    # the best-filled screen of several: the window maps and draws at its own pace
    time.sleep(0.25)
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


@pytest.mark.skipif(shutil.which("xvfb-run") is None or shutil.which("Xvfb") is None,
                    reason="needs xvfb-run and Xvfb (apt install xvfb) for a virtual display")
def test_a_perturbation_in_the_viewer_pulls_the_robot_where_it_is_dragged(netns, tmp_path):
    """What a ctrl+right-drag sets in the viewer (its mjvPerturb: the body and where it is pulled to) moves the
    simulated trunk there and holds it, as in MuJoCo's own simulate; without it the trunk stays put sideways."""
    script = tmp_path / "drag.py"
    script.write_text(f"""
import json, sys
import mujoco, numpy as np
from messages import contract
from sim_hil.sim import SimConfig, Simulator
DRAG_Y_M = {DRAG_Y_M}
out = {{}}
for drag in (False, True):
    sim = Simulator(SimConfig(clock="realtime", spawn="standing", duration_s=0.8, viewer=True,
                              lcm_url=contract.lcm_url()))
    assert sim.viewer is not None, "no viewer window"
    y0 = float(sim.data.xpos[sim.trunk_id][1])
    if drag:
        h = sim.viewer.handle
        with h.lock():
            p = h.perturb
            p.select = sim.trunk_id
            p.active = int(mujoco.mjtPertBit.mjPERT_TRANSLATE)
            p.localpos[:] = 0.0
            p.localmass = float(sim.model.body_subtreemass[sim.trunk_id])
            p.refquat[:] = sim.data.xquat[sim.trunk_id]
            p.refselpos[:] = sim.data.xpos[sim.trunk_id] + np.array([0.0, DRAG_Y_M, 0.0])
    sim.run()
    out["dragged" if drag else "free"] = float(sim.data.xpos[sim.trunk_id][1]) - y0
json.dump(out, open({str(tmp_path / 'drag.json')!r}, "w"))
""")
    proc = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 640x480x24", sys.executable, str(script)],
                          env=_env(), cwd=ROOT, capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr[-3000:]
    moved = json.loads((tmp_path / "drag.json").read_text())
    assert abs(moved["free"]) < 0.05, moved
    assert abs(moved["dragged"] - DRAG_Y_M) < 0.1, moved

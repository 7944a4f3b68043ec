"""`python -m sim_hil --viewer` shows the running robot in MuJoCo's viewer; without a display it says so and the
run completes headless."""
import contextlib
import inspect
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from sim_hil.launch import ROOT, _env

DRAG_Y_M = 0.3      # how far sideways the test's perturbation pulls the trunk [m]
FIRST_FRAME_TIMEOUT_S = 240.0  # from the sim's start: imports, the viewer's launch (≤ 20 s), first draws, under load


def _shows_robot(img) -> bool:
    """The robot is grey in a blue-grey scene with a checker floor: a window (not a uniform screen) holding
    near-neutral grey pixels (the robot's body) beside bluish ones (sky/floor)."""
    r, g, b = (img[..., i].astype(int) for i in range(3))
    neutral = (abs(r - g) < 8) & (abs(g - b) < 8) & (r > 40) & (r < 200)
    bluish = b > r + 15
    return bool(img.std() > 10 and neutral.sum() > 500 and bluish.sum() > 500)


@contextlib.contextmanager
def _virtual_display():
    """The env of an Xvfb server on a display it picks itself (-displayfd: tests running side by side cannot
    race for one number, as `xvfb-run -a`'s probing can), stopped afterwards. -noreset: by default the server
    resets when its last client leaves (a screen grab's), refusing the sim's connection meanwhile."""
    read_end, write_end = os.pipe()
    server = subprocess.Popen(["Xvfb", "-displayfd", str(write_end), "-screen", "0", "640x480x24", "-nolisten",
                               "tcp", "-noreset"], pass_fds=(write_end,), stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE)
    os.close(write_end)
    try:
        with os.fdopen(read_end) as ready:
            number = ready.readline().strip()     # written once the server accepts clients; EOF if it died
        assert number, f"Xvfb did not start: {server.communicate(timeout=10)[1].decode()[-2000:]}"
        yield {**_env(), "DISPLAY": f":{number}"}
    finally:
        server.terminate()
        server.wait(timeout=30)


NEEDS_XVFB = pytest.mark.skipif(shutil.which("Xvfb") is None,
                                reason="needs Xvfb (apt install xvfb) for a virtual display")


def _sim(env, *args):
    return subprocess.Popen([sys.executable, "-m", "sim_hil", "--quiet", "--no-log", "--clock", "realtime", *args],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_viewer_without_a_display_says_so_and_runs_headless(netns):
    env = {k: v for k, v in _env().items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    proc = _sim(env, "--viewer", "--duration", "0.2")
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert "--viewer: no display" in err and "headless" in err and "Traceback" not in err, err


@NEEDS_XVFB
def test_viewer_window_shows_the_robot(netns, tmp_path):
    """The test runs itself on a virtual display and grabs the screen until a frame shows the robot (or the
    timeout), then stops the sim as its users do (SIGTERM: a clean exit)."""
    script = tmp_path / "shot.py"
    script.write_text(inspect.getsource(_shows_robot) + f"""
import os, signal, subprocess, sys, time
import numpy as np
from PIL import ImageGrab
proc = subprocess.Popen([sys.executable, "-m", "sim_hil", "--quiet", "--no-log", "--clock", "realtime", "--viewer",
                         "--duration", "{2 * FIRST_FRAME_TIMEOUT_S}"], cwd={str(ROOT)!r}, stderr=subprocess.PIPE,
                        text=True)
deadline, img = time.monotonic() + {FIRST_FRAME_TIMEOUT_S}, None
while proc.poll() is None and time.monotonic() < deadline:
    img = np.asarray(ImageGrab.grab(xdisplay=os.environ["DISPLAY"]).convert("RGB"))
    if _shows_robot(img):
        break
    time.sleep(0.1)
if img is not None:
    np.save({str(tmp_path / 'shot.npy')!r}, img)
if proc.poll() is None:
    proc.send_signal(signal.SIGTERM)
err = proc.communicate(timeout=30)[1]
sys.stderr.write(err)
sys.exit(proc.returncode)
""")
    with _virtual_display() as env:
        proc = subprocess.run([sys.executable, str(script)], env=env, capture_output=True, text=True,
                              timeout=FIRST_FRAME_TIMEOUT_S + 60)
    assert proc.returncode == 0 and "Traceback" not in proc.stderr and "no display" not in proc.stderr, proc.stderr
    assert "did not open" not in proc.stderr, proc.stderr
    img = np.load(tmp_path / "shot.npy")
    assert _shows_robot(img), (f"no frame showed the robot within {FIRST_FRAME_TIMEOUT_S:g} s (last: std "
                               f"{img.std():.1f}); the sim said: {proc.stderr[-2000:]}")


@NEEDS_XVFB
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
    with _virtual_display() as env:
        proc = subprocess.run([sys.executable, str(script)], env=env, cwd=ROOT, capture_output=True, text=True,
                              timeout=180)
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr[-3000:]
    moved = json.loads((tmp_path / "drag.json").read_text())
    assert abs(moved["free"]) < 0.05, moved
    assert abs(moved["dragged"] - DRAG_Y_M) < 0.1, moved

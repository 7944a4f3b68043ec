"""A recording in Rerun's web viewer as a person sees it: the viewer served on loopback (tools/rerun_viewer's
way, inside whatever namespace the caller is in), opened in headless Chromium, and screenshots taken until a
condition on the picture holds or a timeout passes. The region helpers follow the shipped blueprint's
shares (sim_hil/rerun_view/blueprint.py): the 3-D view is the left 3/5, top 3/4 below the top bar.

`python -m tests.rerun_web RUN.rrd OUT.png` writes the picture the README shows (run it in tools/netns)."""
from __future__ import annotations

import contextlib
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np

from sim_hil.rerun_view.analytics import disable_analytics, rerun_cli
from tests.headless_chromium import Chromium

WIDTH, HEIGHT = 1280, 800
SERVE_TIMEOUT_S = 60.0
POLL_S = 1.0                      # between screenshots while waiting for the view
PIXEL_DIFF = 0.1                  # a pixel differs when a channel differs by more than this (of full scale)
ROBOT_MIN_SHARE = 0.01            # share of the 3-D view's pixels the robot must change against the empty scene
PLOTS_MIN_SHARE = 0.003           # share of coloured pixels in the plot column: the plots are drawn


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def view_3d(img: np.ndarray) -> np.ndarray:
    h, w = img.shape[:2]
    return img[int(0.07 * h):int(0.62 * h), :int(0.58 * w)]


def plot_column(img: np.ndarray) -> np.ndarray:
    h, w = img.shape[:2]
    return img[int(0.07 * h):int(0.83 * h), int(0.62 * w):]


def coloured_share(img: np.ndarray) -> float:
    """Share of saturated pixels (plot lines; the viewer's chrome is grey)."""
    return float(((img.max(axis=-1) - img.min(axis=-1)) > 0.25).mean())


def differing_share(a: np.ndarray, b: np.ndarray) -> float:
    return float((np.abs(a - b).max(axis=-1) > PIXEL_DIFF).mean())


@contextlib.contextmanager
def served(rrd: Path):
    """The web viewer on 127.0.0.1 with `rrd` loaded; yields the page URL."""
    disable_analytics()
    web, grpc = free_port(), free_port()
    proc = subprocess.Popen([rerun_cli(), "--serve-web", "--bind", "127.0.0.1", "--web-viewer-port", str(web),
                             "--port", str(grpc), str(rrd)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    url = f"http://127.0.0.1:{web}/?url=rerun%2Bhttp://127.0.0.1:{grpc}/proxy"
    try:
        deadline = time.monotonic() + SERVE_TIMEOUT_S
        while True:
            try:
                urllib.request.urlopen(f"http://127.0.0.1:{web}/", timeout=2).close()
                break
            except OSError:
                if proc.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError(f"the rerun web viewer did not serve {rrd} (exit {proc.poll()})")
                time.sleep(0.1)
        yield url
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def screenshot_when(rrd: Path, ready, timeout_s: float) -> tuple[np.ndarray, bytes]:
    """The first screenshot of `rrd` in the web viewer for which ready(img) holds; TimeoutError otherwise."""
    with served(rrd) as url:
        browser = Chromium(WIDTH, HEIGHT)
        try:
            browser.open(url)
            deadline = time.monotonic() + timeout_s
            while True:
                img, png = browser.screenshot()
                if ready(img):
                    return img, png
                if time.monotonic() > deadline:
                    raise TimeoutError(f"{rrd}: the web viewer did not show what was waited for in {timeout_s} s")
                time.sleep(POLL_S)
        finally:
            browser.close()


def loaded(img: np.ndarray) -> bool:
    """The recording is on screen: its plots are drawn (a loading viewer is one dark, grey page)."""
    return coloured_share(plot_column(img)) > PLOTS_MIN_SHARE


def robot_screenshot(full: Path, empty: Path, timeout_s: float):
    """(empty scene, robot scene, both PNGs, share of the 3-D view the robot changed): each taken once its
    recording is on screen, the robot's once its 3-D view also differs from the empty scene's."""
    empty_img, empty_png = screenshot_when(empty, loaded, timeout_s)
    robot_img, png = screenshot_when(
        full, lambda img: loaded(img) and differing_share(view_3d(img), view_3d(empty_img)) > ROBOT_MIN_SHARE,
        timeout_s)
    return empty_img, robot_img, (empty_png, png), differing_share(view_3d(robot_img), view_3d(empty_img))


if __name__ == "__main__":
    rrd, out = Path(sys.argv[1]), Path(sys.argv[2])
    from sim_hil.lcmlog.eventlog import open_log
    from sim_hil.rerun_view.convert import convert
    empty = out.with_suffix(".empty.rrd")
    convert(open_log(rrd.with_suffix(".lcmlog")), empty, with_robot=False)
    *_, (_, png), share = robot_screenshot(rrd, empty, 300)
    out.write_bytes(png)
    empty.unlink()
    print(f"{out}: the robot changes {share:.1%} of the 3-D view")

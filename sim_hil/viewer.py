"""`python -m sim_hil --viewer`: MuJoCo's own interactive viewer on the running simulation (a live view).

The passive viewer renders on its own thread (GLFW, needs an X display; it does not use MUJOCO_GL, so it
coexists with --record's offscreen osmesa/egl renderer). The sim's loop calls maybe_sync() after each tick;
it syncs only at SYNC_HZ of wall time, so realtime pacing keeps its 2 ms tick, and a sim without --viewer
has no viewer object at all (zero per-tick cost).

What it shows: the camera tracks the Trunk; an arrow from the trunk is the current joystick command
(T1_JOYSTICK, heading frame); text gives the runtime's mode (T1_CONTROLLER_STATUS), fallen (trunk below
FALLEN_TRUNK_HEIGHT_M, as in T1_SIM_STATUS) and the active faults. A mouse perturbation (double-click a body,
ctrl+right-drag to pull, ctrl+left-drag to twist) reaches the physics: the viewer's perturbation (the body,
its reference pose) is copied at each display sync and the sim turns it into a force on its own state at
every physics step, as MuJoCo's own simulate does (a force computed at display rate from a snapshot and
held between syncs is a stale spring: it overshoots and throws the robot).
"""
from __future__ import annotations

import os
import sys
import threading
import time

import mujoco
import numpy as np

from common.events import FALLEN_TRUNK_HEIGHT_M
from sim_hil.runtime_view import RuntimeView

SYNC_HZ = 30.0                 # wall-clock display rate; a sync copies mjData (well under 1 ms)
LAUNCH_TIMEOUT_S = 20.0        # launch_passive blocks forever if its thread dies (no GLX ...): give up then
ARROW_M_PER_MPS = 1.0          # arrow length per m/s of commanded speed
ARROW_RGBA = np.array([1.0, 0.55, 0.0, 1.0], dtype=np.float32)


def _say(msg: str) -> None:
    print(f"sim_hil: --viewer: {msg}", file=sys.stderr, flush=True)


def _launch(model: mujoco.MjModel, data: mujoco.MjData):
    """(handle, render thread), or None with the reason printed."""
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        _say("no display ($DISPLAY is unset): the simulation goes on headless")
        return None
    try:
        import glfw
        import mujoco.viewer
    except Exception as exc:  # noqa: BLE001 - glfw missing, or its library cannot load
        _say(f"cannot load GLFW ({type(exc).__name__}: {exc}): the simulation goes on headless")
        return None
    # glfw.init in the viewer's thread failing would leave launch_passive waiting forever: try it here first.
    if not glfw.init():
        _say(f"cannot open display {os.environ.get('DISPLAY')!r}: the simulation goes on headless")
        return None
    before = set(threading.enumerate())
    result: list = []
    caller = threading.Thread(target=lambda: result.append(mujoco.viewer.launch_passive(
        model, data, show_left_ui=False, show_right_ui=False)), daemon=True)
    caller.start()
    caller.join(LAUNCH_TIMEOUT_S)
    if not result:
        _say(f"the viewer did not open within {LAUNCH_TIMEOUT_S:g} s: the simulation goes on headless")
        return None
    # launch_passive does not return its render thread; it is the one it started. Joining it after close()
    # is the clean shutdown: a daemon render thread killed at interpreter exit segfaults.
    render = [t for t in threading.enumerate() if t not in before and t is not caller]
    return result[0], (render[0] if render else None)


_PERTURB_FIELDS = ("select", "flexselect", "skinselect", "active", "active2", "refpos", "refquat", "refselpos",
                   "localpos", "localmass", "scale")


def _copy_perturb(src: mujoco.MjvPerturb) -> mujoco.MjvPerturb:
    out = mujoco.MjvPerturb()
    for name in _PERTURB_FIELDS:
        value = getattr(src, name)
        if isinstance(value, np.ndarray):
            getattr(out, name)[:] = value
        else:
            setattr(out, name, value)
    return out


class LiveViewer:
    """The viewer shows its own MjData (`view`), never the sim's: a sync waits for the render thread's frame
    (~0.1 s with software GL), so it runs on a thread of its own, and the sim only hands over a snapshot of
    its state at display rate when that thread is free (it never waits). The mouse's perturbation comes
    back the same way: the sync thread copies it, the sim applies it every step (apply_perturbation)."""

    def __init__(self, handle, render_thread, sim, view: mujoco.MjData):
        self.handle, self.render_thread, self.view = handle, render_thread, view
        self.model, self.data, self.trunk_id = sim.model, sim.data, sim.trunk_id
        self._period = 1.0 / SYNC_HZ
        self._next = 0.0
        self._closed_said = False
        self._pending = threading.Event()     # a snapshot is in `view` for the sync thread
        self._perturb: mujoco.MjvPerturb | None = None   # the mouse's, as of the last sync (replaced whole)
        self._perturbed_body = 0              # the body whose xfrc_applied the perturbation last set
        self._faults = "none"
        self._stop = False
        self._syncer = threading.Thread(target=self._sync_loop, daemon=True)
        self._syncer.start()
        self.runtime = RuntimeView(sim.link)   # decoded at display rate only
        with handle.lock():
            cam = handle.cam
            cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
            cam.trackbodyid = self.trunk_id
            cam.distance, cam.elevation, cam.azimuth = 3.0, -15.0, 135.0

    @classmethod
    def open(cls, sim) -> "LiveViewer | None":
        view = mujoco.MjData(sim.model)
        launched = _launch(sim.model, view)
        return None if launched is None else cls(*launched, sim, view)

    def maybe_sync(self, sim) -> None:
        """Called by the sim after every tick; costs a clock read unless a snapshot is due and taken."""
        now = time.perf_counter()
        if now < self._next or self._pending.is_set():
            return
        self._next = now + self._period
        if not self.handle.is_running():
            if not self._closed_said:
                _say("window closed: the simulation goes on headless")
                self._closed_said = True
            return
        self.view.qpos[:], self.view.qvel[:], self.view.time = sim.data.qpos, sim.data.qvel, sim.data.time
        self._faults = sim.faults.describe(sim.data.time) or "none"
        self._pending.set()

    def _sync_loop(self) -> None:
        while not self._stop:
            if not self._pending.wait(0.1):
                continue
            mujoco.mj_forward(self.model, self.view)
            self._update_overlays()     # the overlays take the viewer's lock too: not on the sim's thread
            self.handle.sync()          # waits for the render thread; the sim does not
            with self.handle.lock():
                self._perturb = _copy_perturb(self.handle.perturb)
            self._pending.clear()

    def apply_perturbation(self, data: mujoco.MjData) -> None:
        """Before each physics step: the mouse's pull on its body's xfrc_applied, computed from the sim's own
        state (the sim's pushes are added on top and removed after their step)."""
        pert = self._perturb
        if self._perturbed_body:
            data.xfrc_applied[self._perturbed_body] = 0.0
            self._perturbed_body = 0
        if pert is not None and pert.active and pert.select > 0:
            mujoco.mjv_applyPerturbForce(self.model, data, pert)
            self._perturbed_body = int(pert.select)

    def _update_overlays(self) -> None:
        vx, vy, wz = self.runtime.command()
        t = self.view.time
        trunk_h = float(self.view.xpos[self.trunk_id][2])
        faults = self._faults
        fallen = "FALLEN" if trunk_h < FALLEN_TRUNK_HEIGHT_M else "upright"
        self.handle.set_texts([(None, mujoco.mjtGridPos.mjGRID_TOPLEFT,
                                "t\nmode\ncommand\nstate\nfaults",
                                f"{t:.2f} s\n{self.runtime.mode()}\n"
                                f"vx {vx:+.2f} vy {vy:+.2f} m/s, yaw {wz:+.2f} rad/s\n"
                                f"{fallen} (trunk {trunk_h:.2f} m)\n{faults}")])
        with self.handle.lock():
            scn = self.handle.user_scn
            scn.ngeom = 0
            if np.hypot(vx, vy) < 1e-3:
                return
            # The command is in the heading frame: rotate it by the trunk's yaw into the world.
            w, x, y, z = self.view.qpos[3:7]
            yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
            c, s = np.cos(yaw), np.sin(yaw)
            start = self.view.xpos[self.trunk_id] + np.array([0.0, 0.0, 0.45])
            end = start + ARROW_M_PER_MPS * np.array([c * vx - s * vy, s * vx + c * vy, 0.0])
            geom = scn.geoms[0]
            mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_ARROW, np.zeros(3), np.zeros(3), np.eye(3).ravel(),
                                ARROW_RGBA)
            mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_ARROW, 0.03, start, end)
            scn.ngeom = 1

    def close(self) -> None:
        self._stop = True
        self._syncer.join(5.0)
        self.handle.close()
        if self.render_thread is not None:
            self.render_thread.join(5.0)

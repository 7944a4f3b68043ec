"""What the simulator hears of its controller: the newest joystick command (T1_JOYSTICK) and the runtime's
mode and fault (T1_CONTROLLER_STATUS), for the live viewer's overlay and the recorded video's caption. The
handlers run inside the sim's LCM polling, so they keep raw payloads; decoding waits for a reader."""
from __future__ import annotations

from t1 import controller_status_t, joystick_t

from messages import contract


class RuntimeView:
    def __init__(self, link):
        self._joystick: bytes | None = None
        self._status: bytes | None = None
        link.subscribe(contract.CH_JOYSTICK, lambda _c, d: setattr(self, "_joystick", d))
        link.subscribe(contract.CH_CONTROLLER_STATUS, lambda _c, d: setattr(self, "_status", d))

    def command(self) -> tuple[float, float, float]:
        """(vx [m/s], vy [m/s], yaw rate [rad/s]); zero before the first joystick message."""
        if self._joystick is None:
            return 0.0, 0.0, 0.0
        js = joystick_t.decode(self._joystick)
        return js.vx, js.vy, js.yaw_rate

    def mode(self) -> str:
        """The runtime's mode, with the fault's text in FAULT; "no runtime" before its first status."""
        if self._status is None:
            return "no runtime"
        st = controller_status_t.decode(self._status)
        return st.mode_name + (f" ({st.last_fault})" if st.mode_name == "FAULT" and st.last_fault else "")

    def caption(self, t_s: float) -> str:
        vx, vy, wz = self.command()
        return f"t {t_s:5.2f} s  {self.mode()}\ncommand vx {vx:+.2f} vy {vy:+.2f} m/s, yaw {wz:+.2f} rad/s"

"""sim_hil.teleop: the core's scaling and deadman, recorded evdev events through the gamepad reader's own
code path (a pipe standing in for /dev/input/eventN: no /dev/uinput here), the keyboard through a pty, an
estop button that puts a running t1-runtime in DAMPING, and the clear errors for bad input."""
from __future__ import annotations

import os
import pty
import subprocess
import sys
import threading
import time
from pathlib import Path

import lcm
import pytest
from evdev import ecodes
from t1 import joystick_t

from messages import contract
from messages.auth import RunKey, new_sender, signed_body, tag, write_key_file
from sim_hil.teleop.__main__ import LcmPublisher, main, run
from sim_hil.teleop.core import KEY_RELEASE_TIMEOUT_S, TeleopCore, command_ranges, load_bindings
from sim_hil.teleop.readers import EVENT, GamepadReader
from tests.runtime_peer import MODE, RuntimePeer

ROOT = Path(__file__).resolve().parents[1]
STUDENT = ROOT / "policies" / "student" / "student.safetensors"
UNTRAINED = ROOT / "policies" / "student_untrained" / "student_untrained.safetensors"
RANGES = command_ranges(STUDENT)            # vx ±1.0, vy ±0.8, yaw_rate ±1.0 in the shipped student
AXIS = (-32768, 32767)                      # a typical pad's stick range (EVIOCGABS min, max)
ABSINFO = {ecodes.ABS_X: AXIS, ecodes.ABS_Y: AXIS, ecodes.ABS_RX: AXIS}


def ev(etype: int, code: int, value: int) -> bytes:
    return EVENT.pack(0, 0, etype, code, value)


def syn() -> bytes:
    return ev(ecodes.EV_SYN, ecodes.SYN_REPORT, 0)


class FakeClock:
    def __init__(self):
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


# ---------------------------------------------------------------- core + reader, no LCM
def test_recorded_stick_events_scale_into_the_command_ranges_only_while_the_deadman_is_held():
    core = TeleopCore(RANGES, clock=FakeClock())
    r, w = os.pipe()
    reader = GamepadReader(r, ABSINFO, load_bindings(None))
    # stick full up (evdev min) = full forward; right stick full left = counter-clockwise; left stick half right
    os.write(w, ev(ecodes.EV_ABS, ecodes.ABS_Y, AXIS[0]) + ev(ecodes.EV_ABS, ecodes.ABS_RX, AXIS[0])
             + ev(ecodes.EV_ABS, ecodes.ABS_X, 16384) + syn())
    reader.read_into(core)
    assert core.command() == (0.0, 0.0, 0.0), "sticks live without the deadman"
    os.write(w, ev(ecodes.EV_KEY, ecodes.BTN_TL, 1) + syn())
    reader.read_into(core)
    vx, vy, yaw = core.command()
    assert vx == pytest.approx(RANGES["vx"][1], abs=1e-3)
    assert vy == pytest.approx(-0.5 * abs(RANGES["vy"][0]), abs=1e-3)       # right = negative vy
    assert yaw == pytest.approx(RANGES["yaw_rate"][1], abs=1e-3)
    os.write(w, ev(ecodes.EV_KEY, ecodes.BTN_TL, 0) + syn())
    reader.read_into(core)
    assert core.command() == (0.0, 0.0, 0.0), "deadman released, command not zero"
    os.close(r), os.close(w)


def test_a_record_split_across_reads_is_kept_and_buttons_send_their_verbs():
    core = TeleopCore(RANGES, load_path="/x.safetensors", clock=FakeClock())
    r, w = os.pipe()
    reader = GamepadReader(r, ABSINFO, load_bindings(None))
    data = ev(ecodes.EV_KEY, ecodes.BTN_EAST, 1) + ev(ecodes.EV_KEY, ecodes.BTN_START, 1)
    os.write(w, data[:30])
    assert reader.read_into(core) == [("estop", "")]
    os.write(w, data[30:] + ev(ecodes.EV_KEY, ecodes.BTN_START, 0))
    assert reader.read_into(core) == [("load_policy", "/x.safetensors")], "release must not send again"
    os.close(r), os.close(w)


def test_keyboard_axis_expires_after_the_release_timeout():
    clock = FakeClock()
    core = TeleopCore(RANGES, clock=clock)
    assert core.key("w") == [] and core.command()[0] > 0
    clock.t += KEY_RELEASE_TIMEOUT_S * 0.8
    core.key("a")                                  # another axis' key does not keep vx alive
    clock.t += KEY_RELEASE_TIMEOUT_S * 0.4
    vx, vy, _ = core.command()
    assert vx == 0.0 and vy > 0
    assert core.key(" ") == [("estop", "")] and core.command() == (0.0, 0.0, 0.0)
    assert core.key("1") == [("set_mode", "prepare")] and core.key("2") == [("set_mode", "policy")]


@pytest.mark.parametrize("argv, message", [
    (["--policy", "README.md"], "--policy README.md: not a policy artifact"),
    (["--bindings", "/nonexistent/keys.json"], "key binding file /nonexistent/keys.json: cannot read it"),
    (["--device", "README.md"], "--device README.md: not an input device"),
])
def test_bad_input_is_refused_with_a_message_naming_it(argv, message, capsys):
    assert main(argv) == 2
    assert message in capsys.readouterr().err


def test_a_binding_to_an_unknown_action_is_refused(tmp_path):
    f = tmp_path / "keys.json"
    f.write_text('{"keys": {"k": "fly"}}')
    with pytest.raises(ValueError, match="unknown action"):
        load_bindings(f)


# ---------------------------------------------------------------- over LCM (project namespace)
class Joysticks:
    def __init__(self):
        self.lc = lcm.LCM(contract.lcm_url())
        self.msgs: list[joystick_t] = []
        self.raw: list[bytes] = []
        self.lc.subscribe(contract.CH_JOYSTICK, self._take)

    def _take(self, _channel, data: bytes) -> None:
        self.raw.append(data)
        self.msgs.append(joystick_t.decode(data))

    def collect(self, seconds: float) -> list[joystick_t]:
        n, end = len(self.msgs), time.monotonic() + seconds
        while time.monotonic() < end:
            self.lc.handle_timeout(10)
        return self.msgs[n:]


def test_pad_stick_and_deadman_reach_t1_joystick_at_the_publish_rate(netns):
    sub = Joysticks()
    r, w = os.pipe()
    core = TeleopCore(RANGES)
    loop = threading.Thread(target=run, args=(core, [GamepadReader(r, ABSINFO, load_bindings(None))],
                                              LcmPublisher(contract.lcm_url(), RunKey().signer()), 5.0),
                            kwargs={"log": lambda s: None})
    loop.start()
    try:
        os.write(w, ev(ecodes.EV_KEY, ecodes.BTN_TR, 1) + ev(ecodes.EV_ABS, ecodes.ABS_Y, AXIS[0]) + syn())
        sub.collect(0.1)
        held = sub.collect(0.5)
        assert 15 <= len(held) <= 35, f"{len(held)} messages in 0.5 s at 50 Hz"
        assert all(m.vx == pytest.approx(RANGES["vx"][1], abs=1e-3) and m.vy == 0 for m in held)
        os.write(w, ev(ecodes.EV_KEY, ecodes.BTN_TR, 0) + syn())
        sub.collect(0.1)
        assert all(m.vx == 0 for m in sub.collect(0.2)), "deadman released, still moving"
    finally:
        os.close(w)                 # end of the recorded stream ends the loop
        loop.join(5)
    assert not loop.is_alive()


def test_estop_button_puts_a_running_runtime_in_damping(netns):
    peer = RuntimePeer(UNTRAINED, "--prepare-s", "0.02", lockstep=True)
    r, w = os.pipe()
    loop = threading.Thread(target=run, args=(TeleopCore(RANGES), [GamepadReader(r, ABSINFO, load_bindings(None))],
                                              LcmPublisher(contract.lcm_url(), peer.signer), 20.0),
                            kwargs={"log": lambda s: None})
    loop.start()
    try:
        peer.steps(5)
        os.write(w, ev(ecodes.EV_KEY, ecodes.BTN_NORTH, 1) + ev(ecodes.EV_KEY, ecodes.BTN_NORTH, 0))  # damping
        peer.until_mode("DAMPING", max_ticks=500)                      # the ladder: PASSIVE → DAMPING → PREPARE
        os.write(w, ev(ecodes.EV_KEY, ecodes.BTN_WEST, 1) + ev(ecodes.EV_KEY, ecodes.BTN_WEST, 0))   # prepare
        peer.until_mode("PREPARE", max_ticks=500)
        peer.steps(30)                                                 # the 10-tick prepare ramp completes
        os.write(w, ev(ecodes.EV_KEY, ecodes.BTN_SOUTH, 1) + ev(ecodes.EV_KEY, ecodes.BTN_SOUTH, 0))  # policy
        peer.until_mode("POLICY", max_ticks=500)
        os.write(w, ev(ecodes.EV_KEY, ecodes.BTN_EAST, 1))                                           # estop
        peer.until_mode("DAMPING", max_ticks=500)
        assert {c.mode for c in peer.steps(50)} == {MODE["DAMPING"]}
        status = peer.last_status()                                    # T1_CONTROLLER_STATUS says so too
        assert status.mode == MODE["DAMPING"], status.mode_name
    finally:
        os.close(w)
        loop.join(5)
        peer.close()


def test_keyboard_through_a_pty_drives_t1_joystick_and_stops_after_the_timeout(netns, tmp_path):
    sub = Joysticks()
    master, slave = pty.openpty()
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(ROOT / "build" / "gen" / "python")]))
    operator = new_sender(5)
    write_key_file(tmp_path / "operator.key", [operator])
    proc = subprocess.Popen([sys.executable, "-m", "sim_hil.teleop", "--keyboard", "--duration", "8",
                             "--key", str(tmp_path / "operator.key")],
                            stdin=slave, stdout=slave, stderr=slave, cwd=ROOT, env=env)
    os.close(slave)
    try:
        deadline = time.monotonic() + 10.0                             # python start-up
        while not sub.collect(0.1):
            assert time.monotonic() < deadline and proc.poll() is None, "teleop published nothing"
        deadline = time.monotonic() + 10.0                             # a held key, as the terminal repeats it
        while not any(m.vx > 0 for m in sub.collect(0.05)):
            assert time.monotonic() < deadline, "a held forward key never reached T1_JOYSTICK"
            os.write(master, b"w")
        deadline = time.monotonic() + 10.0
        os.write(master, b"\x1b[D")                                     # left arrow: turn counter-clockwise
        while not any(m.yaw_rate > 0 for m in sub.collect(0.05)):
            assert time.monotonic() < deadline, "the left arrow never turned the command"
        deadline = time.monotonic() + 10.0                             # no key for the release timeout: stop
        while not any(m.vx == 0 and m.yaw_rate == 0 for m in sub.collect(KEY_RELEASE_TIMEOUT_S)):
            assert time.monotonic() < deadline, "no key for the release timeout, still moving"
        assert all(m.vx == 0 and m.yaw_rate == 0 for m in sub.collect(0.2)), "released, yet moving again"
        os.write(master, b"\x03")                                       # Ctrl-C: stops, sends a zero command
        assert proc.wait(5) == 0
        assert sub.msgs and all(m.sender_id == 5 and m.tag == tag(operator.key, contract.CH_JOYSTICK, signed_body(d))
                                for m, d in zip(sub.msgs, sub.raw))
    finally:
        if proc.poll() is None:
            proc.kill()
        os.close(master)

"""Device readers for the teleop: a Linux evdev gamepad and a terminal keyboard. Each is a select()-able
object whose read_into(core) turns the bytes waiting on its fd into TeleopCore calls and returns the verbs
they produced.

The gamepad's event loop parses struct input_event records itself (EVENT below) from the device fd, and
uses the `evdev` package only to find and check the device and read its axis ranges (ioctls). So a
recorded stream of input_event records on a pipe or file goes through exactly the code a live pad does:
that is how the tests drive it (this machine has no /dev/uinput)."""
from __future__ import annotations

import os
import struct
import termios
import tty

from evdev import ecodes

from sim_hil.teleop.core import TeleopCore

# struct input_event on 64-bit Linux: struct timeval {long tv_sec; long tv_usec}; __u16 type, code; __s32 value
EVENT = struct.Struct("llHHi")
READ_CHUNK_BYTES = EVENT.size * 64


class DeviceGone(Exception):
    """The device went away (pad unplugged, recorded stream ended, terminal closed)."""


def _names(table: dict, code: int) -> list[str]:
    """evdev name(s) of a code: ecodes.BTN[0x130] is ['BTN_A', 'BTN_GAMEPAD', 'BTN_SOUTH']."""
    names = table.get(code, [])
    return [names] if isinstance(names, str) else list(names)


class GamepadReader:
    """Reads input_event records from `fd`. absinfo: {ABS code: (min, max)} for the bound axes."""

    def __init__(self, fd: int, absinfo: dict[int, tuple[int, int]], bindings: dict[str, dict], name: str = "gamepad"):
        for section, known in (("buttons", ecodes.ecodes), ("axes", ecodes.ecodes)):
            for key in bindings[section]:
                if key not in known:
                    raise ValueError(f"bindings: {section} entry {key!r} is not an evdev code name "
                                     "(e.g. BTN_EAST, ABS_X)")
        self.fd, self.absinfo, self.bindings, self.name = fd, absinfo, bindings, name
        self._buffer = b""
        self._device = None   # the evdev.InputDevice that owns fd, when opened by open()

    @classmethod
    def open(cls, path: str, bindings: dict[str, dict]) -> "GamepadReader":
        """A live pad at /dev/input/eventN. ValueError when the path is not an input device or not a pad."""
        import evdev  # imported here: the recorded-stream path needs only ecodes
        try:
            dev = evdev.InputDevice(path)
        except FileNotFoundError as e:
            raise ValueError(f"--device {path}: no such file") from e
        except PermissionError as e:
            raise ValueError(f"--device {path}: permission denied (add yourself to group 'input')") from e
        except OSError as e:   # ENOTTY from the EVIOCGNAME ioctl on a file that is not an evdev node
            raise ValueError(f"--device {path}: not an input device ({e.strerror})") from e
        caps = dev.capabilities()
        axes = {code: (info.min, info.max) for code, info in caps.get(ecodes.EV_ABS, [])}
        wanted = [ecodes.ecodes[n] for n in bindings["axes"]]
        if not all(code in axes for code in wanted):
            dev.close()
            raise ValueError(f"--device {path} ({dev.name}): not a gamepad: it lacks the axes "
                             f"{sorted(bindings['axes'])} (bindings 'axes')")
        reader = cls(dev.fd, {code: axes[code] for code in wanted}, bindings, dev.name)
        reader._device = dev
        return reader

    def fileno(self) -> int:
        return self.fd

    def read_into(self, core: TeleopCore) -> list[tuple[str, str]]:
        try:
            chunk = os.read(self.fd, READ_CHUNK_BYTES)
        except BlockingIOError:
            return []
        except OSError as e:   # ENODEV: unplugged
            raise DeviceGone(f"{self.name}: {e.strerror}") from e
        if not chunk:
            raise DeviceGone(f"{self.name}: end of event stream")
        self._buffer += chunk
        verbs = []
        whole = len(self._buffer) - len(self._buffer) % EVENT.size   # a pipe may split a record
        for _sec, _usec, etype, code, value in EVENT.iter_unpack(self._buffer[:whole]):
            verbs += self.handle(core, etype, code, value)
        self._buffer = self._buffer[whole:]
        return verbs

    def handle(self, core: TeleopCore, etype: int, code: int, value: int) -> list[tuple[str, str]]:
        """One event → core. EV_KEY value 2 is autorepeat: not a new press."""
        if etype == ecodes.EV_KEY and value in (0, 1):
            for name in _names(ecodes.BTN, code) + _names(ecodes.KEY, code):
                if name in self.bindings["buttons"]:
                    return core.pad_button(name, value == 1)
        elif etype == ecodes.EV_ABS and code in self.absinfo:
            lo, hi = self.absinfo[code]
            centre, half = (lo + hi) / 2.0, max((hi - lo) / 2.0, 1e-9)
            for name in _names(ecodes.ABS, code):
                core.pad_axis(name, (value - centre) / half)
        return []

    def close(self) -> None:
        if self._device is not None:
            self._device.close()


def find_gamepad(bindings: dict[str, dict]) -> GamepadReader | None:
    """The first /dev/input/event* that has the bound sticks and a gamepad button; None when there is none."""
    import evdev
    for path in sorted(evdev.list_devices()):
        try:
            dev = evdev.InputDevice(path)
        except OSError:
            continue   # unreadable (permissions): not ours to use
        keys = dev.capabilities().get(ecodes.EV_KEY, [])
        dev.close()
        if ecodes.BTN_GAMEPAD in keys:
            try:
                return GamepadReader.open(path, bindings)
            except ValueError:
                continue
    return None


# ---------------------------------------------------------------- keyboard
_ARROWS = {b"A": "up", b"B": "down", b"C": "right", b"D": "left"}


class KeyboardReader:
    """Keys from a terminal fd in cbreak mode (no echo, no line buffering) with ISIG off, so Ctrl-C arrives
    as a key ("ctrl-c" → quit, a clean stop with a zero command) even on a terminal that is not ours.
    A terminal sends no key-up: the core's KEY_RELEASE_TIMEOUT_S stands in for it."""

    def __init__(self, fd: int):
        self.fd = fd
        self._saved = None
        if os.isatty(fd):
            self._saved = termios.tcgetattr(fd)
            tty.setcbreak(fd)
            mode = termios.tcgetattr(fd)
            mode[3] &= ~termios.ISIG      # lflag
            termios.tcsetattr(fd, termios.TCSANOW, mode)
        self._buffer = b""

    def fileno(self) -> int:
        return self.fd

    def read_into(self, core: TeleopCore) -> list[tuple[str, str]]:
        try:
            chunk = os.read(self.fd, 256)
        except OSError as e:   # EIO: the terminal (pty master) closed
            raise DeviceGone(f"terminal: {e.strerror}") from e
        if not chunk:
            raise DeviceGone("terminal: end of input")
        self._buffer += chunk
        verbs = []
        for key in self._keys():
            verbs += core.key(key)
        return verbs

    def _keys(self):
        b = self._buffer
        while b:
            if b[:1] == b"\x1b":
                if len(b) < 3 and b"\x1b[".startswith(b[:2]):
                    break                                   # an arrow's escape sequence, cut by the read: wait
                if b[1:2] == b"[" and b[2:3] in _ARROWS:
                    yield _ARROWS[b[2:3]]
                    b = b[3:]
                    continue
                b = b[1:]                                   # a lone ESC or an unknown sequence: skipped
                continue
            ch, b = b[:1], b[1:]
            yield "ctrl-c" if ch == b"\x03" else ch.decode("latin-1").lower()
        self._buffer = b

    def close(self) -> None:
        if self._saved is not None:
            termios.tcsetattr(self.fd, termios.TCSADRAIN, self._saved)
            self._saved = None

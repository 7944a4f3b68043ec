"""Teleop core: the one table of bindings and a pure state machine (inputs in → velocity command and
runtime verbs out), with the deadman timed against an injected clock. No devices, no LCM here: the
readers (sim_hil/teleop/readers.py) and the tests drive the same methods."""
from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Callable

from common.artifact import read_artifact

# ---------------------------------------------------------------- rates and timeouts (units in the name)
PUBLISH_RATE_HZ = 50.0            # T1_JOYSTICK rate; the runtime zeroes a joystick older than its stale limit
KEY_RELEASE_TIMEOUT_S = 0.25      # keyboard: no key for an axis this long → that axis 0 (terminals send no key-up)
STICK_DEADZONE = 0.10             # |normalised stick| below this reads 0 (pads rest a few % off centre)
KEY_SPEED_FRACTION = 0.5          # one key press commands this fraction of the range's end (keys are not analog)

FIELDS = ("vx", "vy", "yaw_rate")

# ---------------------------------------------------------------- verbs: action name → (runtime_cmd_t verb, argument)
# "load_policy"'s argument (None here) is the --load path given on the command line.
VERBS: dict[str, tuple[str, str | None]] = {
    "estop": ("estop", ""),              # → DAMPING within one runtime tick, from any mode
    "prepare": ("set_mode", "prepare"),
    "policy": ("set_mode", "policy"),
    "damping": ("set_mode", "damping"),
    "passive": ("set_mode", "passive"),
    "reset": ("reset", ""),              # leave FAULT (to DAMPING)
    "load_policy": ("load_policy", None),
}
# Movement actions: "FIELD+" / "FIELD-" (keyboard), and the pad's deadman and "stop" (zero now).
MOVES = {f"{f}{s}": (f, 1.0 if s == "+" else -1.0) for f in FIELDS for s in "+-"}
OTHER_ACTIONS = {"deadman", "stop", "quit"}
ACTIONS = set(VERBS) | set(MOVES) | OTHER_ACTIONS

# ---------------------------------------------------------------- THE mapping table (override with --bindings FILE)
BINDINGS: dict[str, dict] = {
    # terminal keys (single characters, or up/down/left/right, or ctrl-c) → action
    "keys": {
        "w": "vx+", "s": "vx-", "a": "vy+", "d": "vy-", "q": "yaw_rate+", "e": "yaw_rate-",
        "up": "vx+", "down": "vx-", "left": "yaw_rate+", "right": "yaw_rate-",
        " ": "estop", "1": "prepare", "2": "policy", "0": "damping", "r": "reset", "l": "load_policy",
        "x": "stop", "ctrl-c": "quit",
    },
    # evdev button names (Linux gamepad API: SOUTH=A/cross, EAST=B/circle, ...) → action
    "buttons": {
        "BTN_TL": "deadman", "BTN_TR": "deadman",          # either shoulder held = sticks live
        "BTN_EAST": "estop", "BTN_MODE": "estop",
        "BTN_WEST": "prepare", "BTN_SOUTH": "policy", "BTN_NORTH": "damping",
        "BTN_SELECT": "reset", "BTN_START": "load_policy",
    },
    # evdev absolute axes → [command field, sign]; sign -1 because evdev's stick up / right are
    # min / max while the command's forward / left / counter-clockwise are positive
    "axes": {"ABS_Y": ["vx", -1], "ABS_X": ["vy", -1], "ABS_RX": ["yaw_rate", -1]},
}

DEFAULT_POLICY = Path(__file__).resolve().parents[2] / "policies" / "student" / "student.safetensors"


def load_bindings(path: str | Path | None) -> dict[str, dict]:
    """BINDINGS, with the sections of a JSON file merged over it. ValueError naming the file and entry."""
    table = {k: dict(v) for k, v in BINDINGS.items()}
    if path is None:
        return table
    try:
        user = json.loads(Path(path).read_text())
    except OSError as e:
        raise ValueError(f"key binding file {path}: cannot read it ({e.strerror})") from e
    except json.JSONDecodeError as e:
        raise ValueError(f"key binding file {path}: not valid JSON ({e})") from e
    if not isinstance(user, dict) or set(user) - set(table):
        raise ValueError(f"key binding file {path}: expected an object with sections {sorted(table)}")
    for section, entries in user.items():
        if not isinstance(entries, dict):
            raise ValueError(f"key binding file {path}: section '{section}' is not an object")
        for name, action in entries.items():
            if section == "axes":
                ok = isinstance(action, list) and len(action) == 2 and action[0] in FIELDS and action[1] in (1, -1)
                if not ok:
                    raise ValueError(f"key binding file {path}: axes.{name} = {action!r}: expected [field, ±1], "
                                     f"field one of {FIELDS}")
            elif action not in ACTIONS:
                raise ValueError(f"key binding file {path}: {section}.{name!r} = {action!r}: unknown action "
                                 f"(known: {sorted(ACTIONS)})")
        table[section].update(entries)
    return table


def command_ranges(policy: str | Path) -> dict[str, tuple[float, float]]:
    """The artifact manifest's command_ranges {field: (lo, hi)}. ValueError naming the file."""
    try:
        manifest = read_artifact(policy)[3]
    except ValueError as e:
        raise ValueError(f"--policy {policy}: not a policy artifact: {e}") from e
    return {f: (float(manifest["command_ranges"][f][0]), float(manifest["command_ranges"][f][1])) for f in FIELDS}


def scale(normalized: float, lo: float, hi: float) -> float:
    """[-1, 1] → [lo, hi] with 0 → 0 (clamped into the range): half a stick is half the range's end."""
    v = normalized * (hi if normalized >= 0 else -lo)
    return min(max(v, lo), hi)


class TeleopCore:
    """Inputs: pad_axis / pad_button / key (each returns the verbs to send). Output: command(), read at the
    publish rate. Gamepad sticks count only while a deadman button is held; keyboard axes each expire
    KEY_RELEASE_TIMEOUT_S after their last key press."""

    def __init__(self, ranges: dict[str, tuple[float, float]], bindings: dict[str, dict] | None = None,
                 load_path: str = "", clock: Callable[[], float] = time.monotonic):
        self.ranges, self.bindings = ranges, bindings or load_bindings(None)
        self.load_path, self.clock = load_path, clock
        self.stick = dict.fromkeys(FIELDS, 0.0)        # normalised [-1, 1], sign applied
        self.deadman_held: set[str] = set()            # which deadman buttons are down
        self.key_value = dict.fromkeys(FIELDS, 0.0)    # normalised, from keys
        self.key_time = dict.fromkeys(FIELDS, -1e9)    # clock() of the axis' last key [s]
        self.quit = False

    # ---------------------------------------------------------------- inputs
    def pad_axis(self, code_name: str, normalized: float) -> None:
        binding = self.bindings["axes"].get(code_name)
        if binding is None:
            return
        field, sign = binding
        self.stick[field] = 0.0 if abs(normalized) < STICK_DEADZONE else max(-1.0, min(1.0, sign * normalized))

    def pad_button(self, code_name: str, pressed: bool) -> list[tuple[str, str]]:
        action = self.bindings["buttons"].get(code_name)
        if action == "deadman":
            (self.deadman_held.add if pressed else self.deadman_held.discard)(code_name)
            return []
        return self._act(action) if pressed and action else []   # verbs fire on press, not on release

    def key(self, name: str) -> list[tuple[str, str]]:
        return self._act(self.bindings["keys"].get(name))

    def _act(self, action: str | None) -> list[tuple[str, str]]:
        if action in MOVES:
            field, sign = MOVES[action]
            self.key_value[field], self.key_time[field] = sign * KEY_SPEED_FRACTION, self.clock()
        elif action == "stop":
            self.key_time = dict.fromkeys(FIELDS, -1e9)
        elif action == "quit":
            self.quit = True
        elif action in VERBS:
            verb, argument = VERBS[action]
            if action == "estop":   # an estop also drops every velocity source
                self.key_time = dict.fromkeys(FIELDS, -1e9)
            return [(verb, self.load_path if argument is None else argument)]
        return []

    # ---------------------------------------------------------------- output
    def command(self) -> tuple[float, float, float]:
        now = self.clock()
        out = []
        for f in FIELDS:
            n = self.stick[f] if self.deadman_held else 0.0
            if now - self.key_time[f] < KEY_RELEASE_TIMEOUT_S:
                n = self.key_value[f]      # a key pressed just now wins over the stick
            out.append(scale(n, *self.ranges[f]))
        return out[0], out[1], out[2]

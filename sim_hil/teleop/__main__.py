"""python -m sim_hil.teleop: drive the T1 from a gamepad (Linux evdev) or this terminal's keyboard.

Publishes T1_JOYSTICK at PUBLISH_RATE_HZ within the --policy artifact's command_ranges, and the operator's
verbs (estop, prepare, policy, damping, reset, load_policy) on T1_RUNTIME_CMD, as the T1's remote does.
The bindings are the one table in sim_hil/teleop/core.py (BINDINGS; --bindings FILE.json overrides
entries). Run it inside the project namespace (tools/netns), next to the runtime it drives:
`make teleop` starts a sim and the runtime there too (--with-sim). What it sends is signed
(messages/auth.py): with --key FILE (this operator's key file, whose line the runtime's key file holds), or
with --with-sim a fresh key of the run that the runtime it starts takes."""
from __future__ import annotations

import argparse
import math
import select
import subprocess
import sys
import time
from pathlib import Path

import lcm
from t1 import joystick_t, runtime_cmd_t

from messages import contract
from messages.auth import KeyFileError, RunKey, Signer, read_key_file
from sim_hil.launch import BUILD, ROOT, RUNTIME, start_runtime, start_sim, stop
from sim_hil.teleop.core import DEFAULT_POLICY, PUBLISH_RATE_HZ, TeleopCore, command_ranges, load_bindings
from sim_hil.teleop.readers import DeviceGone, GamepadReader, KeyboardReader, find_gamepad

BEHIND_RESYNC_S = 0.5     # publisher this far behind its schedule (suspended, swapped out): restart the schedule
POLICIES = ROOT / "policies"


class LcmPublisher:
    """Publishes the command and the verbs, signed by `signer` (the operator's key)."""

    def __init__(self, url: str, signer: Signer):
        self.lc, self.signer = lcm.LCM(url), signer
        self.js_seq = self.cmd_seq = 0

    def joystick(self, vx: float, vy: float, yaw_rate: float) -> None:
        m = joystick_t()
        self.js_seq += 1
        m.utime, m.seq, m.vx, m.vy, m.yaw_rate = int(time.time() * 1e6), self.js_seq, vx, vy, yaw_rate
        self.lc.publish(contract.CH_JOYSTICK, self.signer.sign(contract.CH_JOYSTICK, m))

    def runtime_cmd(self, verb: str, argument: str) -> None:
        m = runtime_cmd_t()
        self.cmd_seq += 1
        m.utime, m.seq, m.verb, m.argument = int(time.time() * 1e6), self.cmd_seq, verb, argument
        self.lc.publish(contract.CH_RUNTIME_CMD, self.signer.sign(contract.CH_RUNTIME_CMD, m))


def run(core: TeleopCore, readers: list, publisher, duration_s: float | None = None, log=print) -> str:
    """The device loop: feed whatever the readers have into the core, send verbs at once, publish the
    command every 1/PUBLISH_RATE_HZ s. Ends on quit, on a reader's DeviceGone, or after duration_s;
    always publishes a zero command last. Returns why it ended."""
    period_s = 1.0 / PUBLISH_RATE_HZ
    start = next_s = time.monotonic()
    reason = "duration"
    try:
        while not core.quit:
            now = time.monotonic()
            if duration_s is not None and now - start >= duration_s:
                break
            ready, _, _ = select.select(readers, [], [], max(0.0, next_s - now))
            for reader in ready:
                for verb, argument in reader.read_into(core):
                    publisher.runtime_cmd(verb, argument)
                    log(f"teleop: sent {verb} {argument}".rstrip())
            now = time.monotonic()
            if now >= next_s:
                publisher.joystick(*core.command())
                next_s = now + period_s if now - next_s > BEHIND_RESYNC_S else next_s + period_s
        else:
            reason = "quit"
    except DeviceGone as e:
        reason = str(e)
        log(f"teleop: {e}: stopping (zero command sent)")
    finally:
        publisher.joystick(0.0, 0.0, 0.0)
    return reason


def help_text(bindings: dict[str, dict], pad: bool) -> str:
    keys = ", ".join(f"{'space' if k == ' ' else k}={a}" for k, a in bindings["keys"].items())
    lines = [f"teleop: keyboard: {keys}", "teleop: keyboard: a movement key moves while it repeats; "
             "no key for 0.25 s = stop"]
    if pad:
        buttons = ", ".join(f"{b}={a}" for b, a in bindings["buttons"].items())
        lines.append(f"teleop: gamepad: hold a deadman button; sticks {bindings['axes']}; {buttons}")
    return "\n".join(lines)


def start_sim_and_runtime(policy: Path, folder: Path, load: Path, out: Path) -> tuple[list[subprocess.Popen], RunKey]:
    """--with-sim: a realtime sim (standing) and t1-runtime in this namespace, the runtime with a fresh key of
    this run, its policy folder `folder`, --policy and the load_policy artifact approved; their output goes
    to files under `out` (a pipe nobody reads would fill and stall them during a long drive)."""
    out.mkdir(parents=True, exist_ok=True)
    sim = start_sim("--clock", "realtime", "--spawn", "standing", "--scenario", "flat")
    runtime = start_runtime(policy, "--clock", "realtime", "--policy-dir", str(folder),
                            output=open(out / "runtime.log", "w"))
    runtime.run_key.approve(load)
    print(f"teleop: started sim_hil and t1-runtime ({policy}); runtime log {out / 'runtime.log'}; "
          "press 0 (damping), 1 (prepare), 2 (policy), then hold w/a/s/d/q/e to walk", file=sys.stderr)
    return [sim, runtime], runtime.run_key


def operator_signer(key_file: str | None) -> Signer:
    """The signer of --key FILE's first sender; without one a fresh key nobody else has, said on stderr."""
    if key_file:
        return Signer(read_key_file(key_file)[0])
    print("teleop: no --key: signing with a fresh key of this run only; a runtime started elsewhere takes "
          "nothing of it but estop (pass --key FILE, this operator's line of the runtime's key file)", file=sys.stderr)
    return RunKey().signer()


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m sim_hil.teleop", description=__doc__.splitlines()[0])
    p.add_argument("--policy", default=str(DEFAULT_POLICY), help="artifact whose command_ranges bound the command")
    p.add_argument("--load", default=None, help="artifact the load_policy key sends: its name in the runtime's "
                   "policy folder (default: --policy's; with --with-sim a path, inside --policy's folder)")
    p.add_argument("--key", default=None, help="this operator's key file (messages/auth.py); not with --with-sim")
    p.add_argument("--device", default="auto", help="auto (first gamepad, else keyboard) | /dev/input/eventN")
    p.add_argument("--keyboard", action="store_true", help="keyboard only, do not look for a gamepad")
    p.add_argument("--bindings", default=None, help="JSON file of {keys|buttons|axes: {...}} over the table")
    p.add_argument("--duration", type=float, default=None, help="stop after S seconds (default: until Ctrl-C)")
    p.add_argument("--lcm-url", default=None, help="default: $T1_LCM_URL or " + contract.DEFAULT_LCM_URL)
    p.add_argument("--with-sim", action="store_true", help="also start sim_hil and t1-runtime (--policy) here")
    args = p.parse_args(argv)

    try:
        if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
            raise ValueError(f"--duration {args.duration}: must be a finite number of seconds > 0")
        bindings = load_bindings(args.bindings)
        ranges = command_ranges(args.policy)
        pad = None
        if not args.keyboard:
            pad = find_gamepad(bindings) if args.device == "auto" else GamepadReader.open(args.device, bindings)
        if args.with_sim:
            if args.key:
                raise ValueError("--key and --with-sim exclude each other (--with-sim signs with a fresh key)")
            if not RUNTIME.exists():
                raise ValueError(f"{RUNTIME} is not built: run `make build`")
            policy = Path(args.policy).resolve()
            folder = POLICIES if policy.is_relative_to(POLICIES) else policy.parent
            load = Path(args.load).resolve() if args.load else policy
            if not load.is_relative_to(folder):
                raise ValueError(f"--load {args.load}: not inside the runtime's policy folder {folder}")
            load_name = str(load.relative_to(folder))
        else:
            signer = operator_signer(args.key)
            load_name = args.load or Path(args.policy).name
    except (ValueError, KeyFileError) as e:
        print(f"teleop: {e}", file=sys.stderr)
        return 2
    if pad is None and not args.keyboard:
        print("teleop: no gamepad found under /dev/input (or no permission to read it): using the keyboard",
              file=sys.stderr)
    core = TeleopCore(ranges, bindings, load_path=load_name)
    print(help_text(bindings, pad is not None), file=sys.stderr)
    print(f"teleop: command ranges {ranges}" + (f"; gamepad '{pad.name}'" if pad else ""), file=sys.stderr)
    children = []
    if args.with_sim:
        children, run_key = start_sim_and_runtime(policy, folder, load, BUILD.parent / "out" / "teleop")
        signer = run_key.signer()
    keyboard = [KeyboardReader(sys.stdin.fileno())] if sys.stdin.isatty() or pad is None else []
    readers = ([pad] if pad else []) + keyboard
    try:
        reason = run(core, readers, LcmPublisher(args.lcm_url or contract.lcm_url(), signer), args.duration,
                     log=lambda s: print(s, file=sys.stderr))
    except KeyboardInterrupt:
        reason = "interrupted"
    finally:
        for reader in readers:
            reader.close()
        for child in children:
            stop(child)
    print(f"teleop: stopped ({reason})", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

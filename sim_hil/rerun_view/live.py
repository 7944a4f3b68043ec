"""`python -m sim_hil.rerun_view.live`: the project's LCM group as a live Rerun stream, the same entities and
blueprint as a converted log (record.py). A process of its own that only subscribes, like the logger: the
runtime's loop and the simulator never wait for it, and it runs niced below them. It runs inside the project
namespace (it needs the LCM group) and writes the stream to stdout, which tools/rerun_live pipes to a viewer
outside the namespace that listens on the machine's loopback only; --save writes an .rrd instead. SIGINT/SIGTERM: the
last batch is flushed, then it exits 0."""
from __future__ import annotations

import argparse
import os
import signal
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path

import lcm
import rerun as rr

from messages import contract
from sim_hil.lcmlog.eventlog import lcm_type
from sim_hil.rerun_view.analytics import disable_analytics
from sim_hil.rerun_view.blueprint import blueprint
from sim_hil.rerun_view.convert import APPLICATION_ID
from sim_hil.rerun_view.record import RunRecorder
from sim_hil.rerun_view.robot import RobotGeoms

FLUSH_S = 0.1        # batch period [s]: the view lags the run by about this much
HANDLE_MS = 20       # LCM wait per loop turn [ms]
MAX_WAIT_FAILURES = 50   # LCM waits failing in a row before the bridge gives up
NICE = 10                # the bridge yields the CPU to the runtime and the simulator (make bench: Rerun rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m sim_hil.rerun_view.live", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--save", type=Path, default=None, help="write this .rrd instead of streaming to stdout")
    ap.add_argument("--name", default="live", help="recording name shown in the viewer")
    args = ap.parse_args(argv)
    if sys.stdout.isatty() and args.save is None:
        print("sim_hil.rerun_view.live: stdout is a terminal: pipe it to a viewer (tools/rerun_live) or use --save",
              file=sys.stderr)
        return 2
    os.nice(NICE)
    disable_analytics()
    rec = rr.RecordingStream(APPLICATION_ID, send_properties=False)
    if args.save is not None:
        rec.save(args.save, default_blueprint=blueprint())
    else:
        rec.stdout(default_blueprint=blueprint())
    rec.send_recording_name(args.name)
    recorder = RunRecorder(rec, RobotGeoms())
    batch: dict[str, list] = defaultdict(list)
    undecodable: Counter = Counter()

    received: Counter = Counter()

    def on_message(channel: str, data: bytes) -> None:
        received[channel] += 1
        try:
            batch[channel].append((int(time.time() * 1e6), lcm_type(channel).decode(data)))
        except Exception:      # another type version or a damaged datagram: counted and named at the end
            undecodable[channel] += 1

    lc = lcm.LCM(contract.lcm_url())
    for channel in contract.CHANNELS.values():
        lc.subscribe(channel, on_message)
    stopping = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stopping.append(True))
    print(f"sim_hil.rerun_view.live: subscribed to the project's channels on {contract.lcm_url()}", file=sys.stderr,
          flush=True)
    next_flush, failures = time.monotonic() + FLUSH_S, 0
    while not stopping:
        try:
            lc.handle_timeout(HANDLE_MS)
            failures = 0
        except OSError:        # a signal interrupted the wait (its handler runs next); a broken LCM keeps failing
            failures += 1
            if failures > MAX_WAIT_FAILURES:
                raise
        if time.monotonic() >= next_flush:
            recorder.write(batch)
            batch.clear()
            next_flush += FLUSH_S
    recorder.write(batch)
    rec.flush()
    rec.disconnect()
    print(f"sim_hil.rerun_view.live: {sum(received.values())} messages streamed", file=sys.stderr)
    for channel, n in sorted(undecodable.items()):
        print(f"sim_hil.rerun_view.live: {n} messages on {channel} did not decode as this build's "
              f"{contract.CHANNEL_TYPES[channel]} (skipped)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

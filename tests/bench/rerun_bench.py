"""Rerun's cost, in `make bench`: a realtime run of the simulator and t1-runtime (student, standing, the
logger capturing it) without and then with the live Rerun view (the bridge, python -m sim_hil.rerun_view.live,
piped into a Rerun viewer serving on loopback, as tools/rerun_live runs them). Printed:
- converting the first run's log to a recording (`python -m sim_hil.lcmlog rerun`, the whole command) against
  the run's duration; target ≤ 10 %;
- the runtime's wake-up lateness (its controller_status samples in each log) and overruns, without and with
  the live view: the view must add nothing beyond run-to-run noise.

    python -m tests.bench.rerun_bench [--seconds S]   (inside tools/netns; make bench runs it)"""
from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from messages import contract
from sim_hil.launch import ROOT, _env, start_runtime, start_sim, stop, wait_until_listening
from sim_hil.lcmlog.capture import LogCapture, RunInfo
from sim_hil.lcmlog.eventlog import open_log
from sim_hil.rerun_view.analytics import rerun_cli
from sim_hil.rerun_view.live import NICE as LIVE_NICE

POLICY = ROOT / "policies" / "student" / "student.safetensors"
TARGET_CONVERT_SHARE = 0.10        # conversion time / run duration
BRIDGE_START_TIMEOUT_S = 120.0


def _free_port() -> int:
    import socket
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _live_view():
    """The viewer (loopback) reading the bridge's stream through a pipe; returns both, the bridge subscribed."""
    viewer = subprocess.Popen(["nice", "-n", str(LIVE_NICE), rerun_cli(), "--serve-web", "--bind", "127.0.0.1",
                               "--web-viewer-port", str(_free_port()), "--port", str(_free_port()), "-"],
                              stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    bridge = subprocess.Popen([sys.executable, "-m", "sim_hil.rerun_view.live", "--name", "bench"], cwd=ROOT,
                              env=_env(), stdout=viewer.stdin, stderr=subprocess.PIPE, text=True)
    viewer.stdin.close()
    line = bridge.stderr.readline()
    if "subscribed" not in line:
        raise RuntimeError(f"the live bridge did not start: {line}{bridge.stderr.read()[-800:]}")
    return viewer, bridge


def run(seconds: float, log: Path, live: bool) -> dict:
    """One realtime run of `seconds`, captured to `log`; lateness statistics of the runtime from its status."""
    views = _live_view() if live else ()
    try:
        with LogCapture(log, contract.lcm_url(), RunInfo("rerun_bench", "bench", "realtime")):
            runtime = start_runtime(POLICY, "--clock", "realtime", "--autostart")
            wait_until_listening(runtime)
            sim = start_sim("--clock", "realtime", "--spawn", "standing", "--duration", str(seconds))
            sim.wait(timeout=seconds * 10 + 120)
            stop(runtime)
    finally:
        for proc in reversed(views):
            proc.terminate()
            proc.wait(timeout=30)
    status = [m for _, m in open_log(log).messages.get(contract.CH_CONTROLLER_STATUS, [])]
    late = np.array([m.lateness_us_last for m in status])
    states = len(open_log(log).messages.get(contract.CH_JOINT_STATE, []))
    return {"p50": float(np.percentile(late, 50)), "p99": float(np.percentile(late, 99)), "max": float(late.max()),
            "overruns": int(status[-1].overruns), "samples": late.size, "states": states}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=60.0, help="sim seconds per run")
    args = ap.parse_args(argv)
    print(f"\n== Rerun: converting a {args.seconds:g} s log, and the live view's cost to the runtime loop ==")
    with tempfile.TemporaryDirectory() as tmp:
        plain = run(args.seconds, Path(tmp) / "plain.lcmlog", live=False)
        cpu_before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        done = subprocess.run([sys.executable, "-m", "sim_hil.lcmlog", "rerun", str(Path(tmp) / "plain.lcmlog"),
                               "-o", str(Path(tmp) / "plain.rrd")], cwd=ROOT, env=_env(), capture_output=True,
                              text=True)
        convert_s = time.perf_counter() - start
        cpu_after = resource.getrusage(resource.RUSAGE_CHILDREN)
        convert_cpu_s = (cpu_after.ru_utime - cpu_before.ru_utime) + (cpu_after.ru_stime - cpu_before.ru_stime)
        if done.returncode != 0:
            raise RuntimeError(f"sim_hil.lcmlog rerun failed: {done.stderr[-800:]}")
        live = run(args.seconds, Path(tmp) / "live.lcmlog", live=True)
    share = convert_s / args.seconds
    print(f"convert {args.seconds:g} s log ({plain['states']} states): {convert_s:.2f} s wall = {share:.3f} of the run "
          f"({share / TARGET_CONVERT_SHARE:.2f}× the {TARGET_CONVERT_SHARE:.0%} target); CPU {convert_cpu_s:.2f} s = "
          f"{convert_cpu_s / args.seconds:.3f} (wall above CPU: the other processes on these cores)")
    print(f"{'runtime wake-up lateness [us]':<32}{'p50':>9}{'p99':>9}{'max':>9}{'overruns':>10}{'samples':>9}")
    for name, r in (("without the live view", plain), ("with the live view", live)):
        print(f"{name:<32}{r['p50']:>9.1f}{r['p99']:>9.1f}{r['max']:>9.1f}{r['overruns']:>10}{r['samples']:>9}")
    print(f"ratio with / without: p50 {live['p50'] / max(plain['p50'], 1e-9):.2f}, "
          f"p99 {live['p99'] / max(plain['p99'], 1e-9):.2f} (the runtime's status samples, ~23 Hz)")


if __name__ == "__main__":
    main()

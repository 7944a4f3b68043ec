"""`python -m sim_hil.lcmlog`: look at, plot and replay the LCM logs every run writes.

  info   LOG                      events per channel, duration, size per minute, damage found
  plot   LOG [--joints A,B]       PNG: heights, velocity, mode, lateness, q vs q_des (next to LOG)
  spy    LOG [--speed S]          play LOG into lcm-spy (inside tools/netns; xvfb-run when there is no display)
  replay LOG [--policy P|logged]  re-run t1-runtime on LOG's states in lockstep, compare its commands with
                                  the logged ones (inside tools/netns); reports next to LOG
  rerun  LOG [-o RUN.rrd]         a Rerun recording: the robot in 3-D, joints, joystick, mode, faults, timing
                                  (default: LOG with .rrd; open it with `rerun RUN.rrd` or make view-log)
A damaged log (truncated, corrupt bytes, unknown channels, another type version) is read as far as it can
be; each problem is printed. Exit codes: 0 ok, 1 the replay differs from the log, 2 bad arguments or an
unreadable log, 3 the replay could not run."""
from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

from messages import contract
from sim_hil.lcmlog.capture import lcm_tool
from sim_hil.lcmlog.eventlog import open_log, write_events

EXIT_OK, EXIT_DIFFERS, EXIT_USAGE, EXIT_FAILED = 0, 1, 2, 3
SPY_START_S = 3.0            # lcm-spy (a JVM) needs this long to subscribe before the log starts
SPY_HEADLESS_LINGER_S = 2.0  # headless: let lcm-spy take the last messages before it is stopped


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="python -m sim_hil.lcmlog", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True)
    for name in ("info", "plot", "spy", "replay", "rerun"):
        p = sub.add_parser(name)
        p.add_argument("log", type=Path)
        if name == "plot":
            p.add_argument("--joints", default=None, help="comma-separated joint names (messages/contract.json)")
            p.add_argument("--out", type=Path, default=None, help="PNG path (default: LOG with .png)")
        if name == "spy":
            p.add_argument("--speed", type=float, default=1.0, help="playback speed factor")
        if name == "replay":
            p.add_argument("--policy", default="logged", help="artifact to re-run, or 'logged' (the log's own)")
            p.add_argument("--out", type=Path, default=None, help="report stem (default: LOG without suffix)")
        if name == "rerun":
            p.add_argument("-o", "--out", type=Path, default=None, help="recording path (default: LOG with .rrd)")
    return ap


def _require_netns(what: str) -> bool:
    if os.environ.get("T1_NETNS_INSIDE") == "1":
        return True
    print(f"sim_hil.lcmlog {what}: run inside the project network namespace (tools/netns, or make replay)",
          file=sys.stderr)
    return False


def info(log) -> int:
    counts = Counter(ev.channel for ev in log.events)
    states = log.messages.get(contract.CH_JOINT_STATE, [])
    # run time: the sim clock of the states (a lockstep run is faster than the wall clock), else receive time
    span_s = ((states[-1][1].utime - states[0][1].utime) if len(states) > 1 else
              (log.events[-1].timestamp_us - log.events[0].timestamp_us)) * 1e-6
    size_mb = log.path.stat().st_size / 1e6
    run = log.first(contract.CH_RUN_INFO)
    if run is not None:
        print(f"run {run.run_name!r} by {run.producer} ({run.clock}); policy {run.policy_path or '-'} "
              f"{run.policy_hash[:12]}; runtime args: {run.runtime_args or '-'}")
    per_min = f", {size_mb / span_s * 60:.1f} MB per minute of run" if span_s > 0 else ""
    print(f"{log.path}: {len(log.events)} events over {span_s:.2f} s of run, {size_mb:.2f} MB{per_min}")
    for channel, n in sorted(counts.items()):
        rate = f"{n / span_s:8.1f} Hz" if span_s > 0 else ""
        print(f"  {channel:<24} {n:8d} {rate}")
    return EXIT_OK


def spy(log, speed: float) -> int:
    if not _require_netns("spy"):
        return EXIT_USAGE
    if not speed > 0:
        print(f"--speed {speed}: must be > 0", file=sys.stderr)
        return EXIT_USAGE
    jar = Path(os.environ.get("T1_BUILD", "build")) / "gen" / "java" / "t1_lcmtypes.jar"
    env = dict(os.environ, CLASSPATH=str(jar))
    url = contract.lcm_url()
    headless = not os.environ.get("DISPLAY")
    spy_cmd = ["lcm-spy", f"--lcm-url={url}"]
    if headless:
        if not shutil.which("xvfb-run"):
            print("no DISPLAY and no xvfb-run: install xvfb (tools/setup.sh) or run with a display", file=sys.stderr)
            return EXIT_FAILED
        spy_cmd = ["xvfb-run", "-a", *spy_cmd]
    with tempfile.TemporaryDirectory() as tmp:
        playable = log.path
        if log.problems.messages(log.path):    # lcm-logplayer stops at the first damaged byte
            playable = write_events(Path(tmp) / "clean.lcmlog", log.events)
        # its own process group: xvfb-run, the wrapper script and the JVM all go when it is stopped
        spy_proc = subprocess.Popen(spy_cmd, env=env, start_new_session=True,
                                    stdout=subprocess.DEVNULL if headless else None)
        try:
            time.sleep(SPY_START_S)
            print(f"playing {log.path} into lcm-spy on {url} ({'headless, xvfb' if headless else 'display'})")
            played = subprocess.run([lcm_tool("lcm-logplayer"), f"--speed={speed}", f"--lcm-url={url}",
                                     str(playable)])
            if headless:
                time.sleep(SPY_HEADLESS_LINGER_S)
            elif played.returncode == 0:
                print("log played; close lcm-spy to finish")
                spy_proc.wait()
        finally:
            if spy_proc.poll() is None:
                os.killpg(spy_proc.pid, signal.SIGTERM)
                spy_proc.wait()
    if played.returncode != 0:
        print(f"lcm-logplayer exited {played.returncode}", file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK


def replay_cmd(log, policy: str, out: Path | None) -> int:
    from common.artifact import artifact_problem
    from sim_hil.lcmlog.replay import replay, write_report
    if not _require_netns("replay"):
        return EXIT_USAGE
    chosen = None if policy == "logged" else Path(policy)
    problem = None if chosen is None else artifact_problem(chosen)
    if problem:
        print(f"sim_hil.lcmlog replay: --policy {problem}", file=sys.stderr)
        return EXIT_USAGE
    try:
        comparison, _ = replay(log, chosen)
    except ValueError as exc:
        print(f"sim_hil.lcmlog replay: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except RuntimeError as exc:
        print(f"sim_hil.lcmlog replay: {exc}", file=sys.stderr)
        return EXIT_FAILED
    js, txt = write_report(comparison, out or log.path.with_suffix(""))
    print(comparison.text())
    print(f"report: {txt}\n        {js}")
    return EXIT_OK if comparison.identical else EXIT_DIFFERS


def rerun_cmd(path: Path, out: Path | None) -> int:
    from sim_hil.rerun_view.convert import convert, read_for_recording
    try:
        log, batch = read_for_recording(path)
    except (OSError, ValueError) as exc:
        print(f"sim_hil.lcmlog: {exc}", file=sys.stderr)
        return EXIT_USAGE
    for problem in log.problems.messages(log.path):
        print(f"sim_hil.lcmlog: {problem}", file=sys.stderr)
    out = out or log.path.with_suffix(".rrd")
    try:
        rows = convert(log, out, batch=batch)
    except (OSError, RuntimeError) as exc:
        print(f"sim_hil.lcmlog rerun: {exc}", file=sys.stderr)
        return EXIT_FAILED
    print(f"rerun: {out} ({rows.get('robot/geoms', 0)} robot poses, {len(rows)} entities); open it with "
          f"`rerun {out}`")
    return EXIT_OK


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    if args.command == "rerun":       # reads the log its own way (the busy channels column-wise)
        return rerun_cmd(args.log, args.out)
    try:
        log = open_log(args.log)
    except (OSError, ValueError) as exc:
        print(f"sim_hil.lcmlog: {exc}", file=sys.stderr)
        return EXIT_USAGE
    for problem in log.problems.messages(log.path):
        print(f"sim_hil.lcmlog: {problem}", file=sys.stderr)
    if args.command == "info":
        return info(log)
    if args.command == "plot":
        from sim_hil.lcmlog.plot import DEFAULT_JOINTS, parse_joints, plot_log
        try:
            joints = parse_joints(args.joints) if args.joints else DEFAULT_JOINTS
        except ValueError as exc:
            print(f"--joints {exc}", file=sys.stderr)
            return EXIT_USAGE
        print(f"plot: {plot_log(log, args.out or log.path.with_suffix('.png'), joints)}")
        return EXIT_OK
    if args.command == "spy":
        return spy(log, args.speed)
    return replay_cmd(log, args.policy, args.out)


if __name__ == "__main__":
    raise SystemExit(main())

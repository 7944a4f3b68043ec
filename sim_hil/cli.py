"""`python -m sim_hil`: start the simulated T1 and serve it over LCM, or with --dds in the real T1's own DDS
topics (run inside tools/netns)."""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from messages import contract
from sim_hil import config
from sim_hil.faults import FaultSpecError
from sim_hil.launch import stop_cleanly_on_sigterm
from sim_hil.motor_bus import INTERFACES
from sim_hil.wait_notice import WaitNotice

EXIT_OK, EXIT_USAGE, EXIT_RUNTIME = 0, 2, 3


def build_parser() -> argparse.ArgumentParser:
    from common.scenarios import SCENARIOS
    p = argparse.ArgumentParser(prog="python -m sim_hil", description=__doc__,
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--scenario", default="flat", choices=SCENARIOS)
    p.add_argument("--spawn", default="standing", help="standing | kneeling | fallen:SEED")
    p.add_argument("--clock", default="realtime", choices=("realtime", "lockstep"))
    p.add_argument("--seed", type=int, default=0, help="scenario layout, fault and noise draws")
    p.add_argument("--duration", type=float, default=None, help="sim seconds to run (default: forever)")
    p.add_argument("--physics-dt", type=float, default=config.DEFAULT_PHYSICS_DT_S, help="MuJoCo step [s]")
    p.add_argument("--faults", default="", help="fault specs, see sim_hil/faults.py, e.g. 'drop:rate=0.1@2'")
    p.add_argument("--record", metavar="OUT.mp4", help="write a video of the run")
    p.add_argument("--viewer", action="store_true",
                   help="MuJoCo's interactive viewer on the run (needs a display; without one the sim runs headless)")
    p.add_argument("--can-log", metavar="OUT.asc", help="log every CAN frame (.asc, .blf, .csv, .log ...)")
    p.add_argument("--can-interface", default="direct", choices=INTERFACES,
                   help="carrier of the 4 buses' frames: direct = firmware_like's host link in C (fast); "
                        "virtual / udp_multicast = python-can buses (udp_multicast: visible to outside tools)")
    p.add_argument("--python-tick", action="store_true",
                   help="run every lockstep tick in Python (the reference the C++ tick is tested against; slower)")
    p.add_argument("--rt", action="store_true",
                   help="with --clock realtime: SCHED_FIFO priority (needs root or CAP_SYS_NICE; refusal reported)")
    p.add_argument("--lcm-url", default=None, help="default: $T1_LCM_URL or " + contract.DEFAULT_LCM_URL)
    p.add_argument("--robot-key", metavar="FILE", default=None,
                   help="sign every T1_IMU / T1_JOINT_STATE with this robot key file (messages/auth.py, mode 600; "
                        "the runtime's --robot-key): a runtime with the key takes state from this robot only")
    p.add_argument("--lockstep-timeout", type=float, default=config.LOCKSTEP_TIMEOUT_S,
                   help="wall seconds to wait for the command answering a state")
    p.add_argument("--status-rate", type=float, default=config.STATUS_RATE_HZ, help="T1_SIM_STATUS rate [Hz]")
    p.add_argument("--dds", action="store_true",
                   help="be the DDS robot: LowState_ on rt/low_state, LowCmd_ from rt/joint_ctrl (Cyclone DDS, "
                        "domain of messages/contract.json; T1_SIM_STATUS stays on LCM)")
    p.add_argument("--fastdds-compat", action="store_true",
                   help="with --dds: let the robot maker's SDK (Fast DDS) discover this Cyclone participant "
                        "(sim_hil/fastdds_shim.py says why it cannot by itself)")
    p.add_argument("--log", metavar="OUT.lcmlog", default=None,
                   help="LCM log of every project channel (default: out/sim/<scenario>_<spawn>_<clock>_<time>.lcmlog)")
    p.add_argument("--no-log", action="store_true", help="do not write an LCM log")
    p.add_argument("--quiet", action="store_true", help="no status line")
    return p


def _status_line(sim) -> None:
    s = sim.status_message()
    print(f"\rt={sim.data.time:7.2f}s rtf={s.real_time_factor:5.2f} trunk={s.trunk_height:.3f}m "
          f"waist={s.waist_height:.3f}m cmds={sim.link.cmds_received} dropped={s.cmds_dropped} "
          f"timeouts={s.lockstep_timeouts} late_frames={s.frames_late} faults=[{s.active_faults}]   ",
          end="", file=sys.stderr, flush=True)


def _start_log(args, cfg, argv: list[str]):
    """t1-lcm-logger on the sim's URL: everything the sim and whoever talks to it publish (sim_hil/lcmlog)."""
    from sim_hil.lcmlog.capture import LogCapture, RunInfo
    path = Path(args.log) if args.log else config.SIM_LOG_DIR / (
        f"{cfg.scenario}_{cfg.spawn.replace(':', '-')}_{cfg.clock}_{time.strftime('%Y%m%d-%H%M%S')}.lcmlog")
    return LogCapture(path, cfg.lcm_url, RunInfo(run_name=path.stem, producer="sim", clock=cfg.clock,
                                                 sim_args=list(argv)))


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from sim_hil.sim import SimConfig, Simulator
    cfg = SimConfig(scenario=args.scenario, spawn=args.spawn, clock=args.clock, seed=args.seed,
                    duration_s=args.duration, physics_dt_s=args.physics_dt, faults=args.faults,
                    lcm_url=args.lcm_url or contract.lcm_url(), can_interface=args.can_interface,
                    can_log=args.can_log, record=args.record, lockstep_timeout_s=args.lockstep_timeout,
                    status_rate_hz=args.status_rate, dds=args.dds,
                    viewer=args.viewer, rt=args.rt, python_tick=args.python_tick, robot_key=args.robot_key)
    shim = None
    if args.fastdds_compat:
        if not args.dds:
            print("sim_hil: --fastdds-compat needs --dds", file=sys.stderr)
            return EXIT_USAGE
        # Before the participant exists: the shim must hear its first announcement (the next is ~30 s later).
        from sim_hil.fastdds_shim import FastDdsShim
        shim = FastDdsShim()
    try:
        sim = Simulator(cfg)
    except (ValueError, FaultSpecError, OSError) as exc:   # KeyFileError is a ValueError: a refused key file;
        print(f"sim_hil: {exc}", file=sys.stderr)           # OSError: --can-log / --record cannot be written
        return EXIT_USAGE
    except RuntimeError as exc:
        print(f"sim_hil: {exc}", file=sys.stderr)
        return EXIT_RUNTIME
    capture = None if args.no_log else _start_log(args, cfg, argv if argv is not None else sys.argv[1:])
    print(f"sim_hil: {cfg.scenario} spawn={cfg.spawn} clock={cfg.clock} physics_dt={cfg.physics_dt_s}s "
          f"link={sim.link.url}" + (f" log={capture.path}" if capture else ""), file=sys.stderr)
    stop_cleanly_on_sigterm()
    notice = WaitNotice(lambda: sim.awaiting_first_command,
                        lambda s: f"sim_hil: waiting for {sim.link.command_source} ({s:.0f} s; lockstep holds "
                                  "state 0 until it is answered: start t1-runtime --clock lockstep)",
                        config.WAIT_NOTICE_FIRST_S, config.WAIT_NOTICE_PERIOD_S).start()
    try:
        sim.run(None if args.quiet else _status_line)
    except KeyboardInterrupt:
        pass
    finally:
        notice.stop()
        if shim is not None:
            shim.stop()
        if capture is not None:
            capture.stop()
    if not args.quiet:
        print(file=sys.stderr)
    return EXIT_OK

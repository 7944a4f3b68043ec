"""One PNG of a log: trunk and waist height, forward velocity against the joystick command, the runtime's
mode, its wake-up lateness, and q against q_des for chosen joints.

Every series is put on the simulator's clock: each event's logger receive time is mapped to sim time by
interpolating the (receive time, utime) pairs of the logged joint states, so channels stamped by
different clocks (sim time, the runtime's monotonic clock) line up on one axis."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from messages import contract
from sim_hil.lcmlog.eventlog import ProjectLog

DEFAULT_JOINTS = ("Left_Hip_Pitch", "Left_Knee_Pitch", "Left_Ankle_Pitch")
MODE_NAMES = ("PASSIVE", "DAMPING", "PREPARE", "POLICY", "FAULT")   # joint_command_t.MODE_* in order


def parse_joints(text: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in contract.JOINT_NAMES]
    if unknown or not names:
        raise ValueError(f"joints {unknown or text!r}: not in messages/contract.json; one of "
                         f"{', '.join(contract.JOINT_NAMES)}")
    return names


def sim_clock(log: ProjectLog):
    """Logger receive time [us] -> sim time [s] (from the joint states; identity when there are none)."""
    states = log.messages.get(contract.CH_JOINT_STATE, [])
    if len(states) < 2:
        return lambda stamp_us: (np.asarray(stamp_us, float) - log.events[0].timestamp_us) * 1e-6
    recv = np.array([ev.timestamp_us for ev, _ in states], float)
    sim = np.array([m.utime for _, m in states], float) * 1e-6
    return lambda stamp_us: np.interp(np.asarray(stamp_us, float), recv, sim)


def series(log: ProjectLog, channel: str, *fields: str):
    """(sim time [s], one array per field) of a channel; empty arrays when it is not in the log."""
    entries = log.messages.get(channel, [])
    t = sim_clock(log)([ev.timestamp_us for ev, _ in entries]) if entries else np.zeros(0)
    return (t, *(np.array([getattr(m, f) for _, m in entries], float) for f in fields))


def plot_log(log: ProjectLog, out: Path, joints: list[str] | tuple[str, ...] = DEFAULT_JOINTS) -> Path:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(4 + len(joints), 1, figsize=(10, 2.0 * (4 + len(joints))), sharex=True)
    info = log.first(contract.CH_RUN_INFO)
    about = [] if info is None else [info.producer, info.clock] + ([Path(info.policy_path).name] if info.policy_path else [])
    fig.suptitle(" — ".join([log.path.name, ", ".join(about)]) if about else log.path.name)

    def missing(ax, what):
        ax.text(0.5, 0.5, f"{what} not in this log", ha="center", va="center", transform=ax.transAxes)

    t, trunk, waist, vx = series(log, contract.CH_SIM_STATUS, "trunk_height", "waist_height", "forward_velocity")
    ax = axes[0]
    if t.size:
        ax.plot(t, trunk, label="trunk"), ax.plot(t, waist, label="waist"), ax.legend(loc="upper right")
    else:
        missing(ax, "T1_SIM_STATUS")
    ax.set_ylabel("height [m]")
    ax = axes[1]
    if t.size:
        ax.plot(t, vx, label="forward velocity")
    tj, cmd_vx = series(log, contract.CH_JOYSTICK, "vx")
    if tj.size:
        ax.step(tj, cmd_vx, where="post", label="joystick vx", color="k", lw=0.8)
    ax.legend(loc="upper right") if (t.size or tj.size) else missing(ax, "T1_SIM_STATUS and T1_JOYSTICK")
    ax.set_ylabel("v [m/s]")
    tc, mode = series(log, contract.CH_JOINT_CMD, "mode")
    ax = axes[2]
    if tc.size:
        ax.step(tc, mode, where="post")
        ax.set_yticks(range(len(MODE_NAMES)), MODE_NAMES, fontsize=7)
    else:
        missing(ax, "T1_JOINT_CMD")
    ax.set_ylabel("mode")
    ts, late_last, late_p99 = series(log, contract.CH_CONTROLLER_STATUS, "lateness_us_last", "lateness_us_p99")
    ax = axes[3]
    if ts.size:
        ax.plot(ts, late_last, label="last"), ax.plot(ts, late_p99, label="p99"), ax.legend(loc="upper right")
    else:
        missing(ax, "T1_CONTROLLER_STATUS")
    ax.set_ylabel("lateness [us]")
    tq, q = series(log, contract.CH_JOINT_STATE, "q")
    _, q_des = series(log, contract.CH_JOINT_CMD, "q_des")
    for ax, name in zip(axes[4:], joints):
        j = contract.joint_index(name)
        if tq.size:
            ax.plot(tq, q[:, j], label="q")
        if tc.size:
            ax.step(tc, q_des[:, j], where="post", label="q_des", lw=0.8)
        ax.set_ylabel(f"{name}\n[rad]", fontsize=8)
        ax.legend(loc="upper right") if (tq.size or tc.size) else missing(ax, "joint state and command")
    axes[-1].set_xlabel("sim time [s]")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=90)
    plt.close(fig)
    return out

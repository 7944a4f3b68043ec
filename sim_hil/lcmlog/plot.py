"""One PNG of a log: trunk and waist height, forward velocity against the joystick command, the runtime's
mode, its wake-up lateness, and q against q_des for chosen joints.

Every series is put on the simulator's clock: each event's logger receive time is mapped to sim time by
interpolating the (receive time, utime) pairs of the logged joint states, so channels stamped by
different clocks (sim time, the runtime's monotonic clock) line up on one axis."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from t1 import joint_command_t

from messages import contract
from sim_hil.lcmlog.eventlog import ProjectLog

DEFAULT_JOINTS = ("Left_Hip_Pitch", "Left_Knee_Pitch", "Left_Ankle_Pitch")
MODE_NAMES = sorted(("PASSIVE", "DAMPING", "PREPARE", "POLICY", "FAULT"),
                    key=lambda name: getattr(joint_command_t, f"MODE_{name}"))   # y tick k = mode number k


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


def _panel(ax, ylabel: str, needs: str, lines) -> None:
    """Plot (t, y, label) lines ("(step)" in a label: a held command, drawn as steps); say so when none is
    in the log."""
    drawn = [(t, y, label) for t, y, label in lines if t.size]
    for t, y, label in drawn:
        if label.endswith("(step)"):
            ax.step(t, y, where="post", label=label.removesuffix(" (step)"), lw=0.8)
        else:
            ax.plot(t, y, label=label)
    if drawn:
        ax.legend(loc="upper right", fontsize=7)
    else:
        ax.text(0.5, 0.5, f"{needs} not in this log", ha="center", va="center", transform=ax.transAxes)
    ax.set_ylabel(ylabel, fontsize=8)


def plot_log(log: ProjectLog, out: Path, joints: list[str] | tuple[str, ...] = DEFAULT_JOINTS) -> Path:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(4 + len(joints), 1, figsize=(10, 2.0 * (4 + len(joints))), sharex=True)
    info = log.first(contract.CH_RUN_INFO)
    about = [] if info is None else [info.producer, info.clock, Path(info.policy_path).name if info.policy_path else ""]
    fig.suptitle(" — ".join([log.path.name, ", ".join(a for a in about if a)]) if about else log.path.name)

    t, trunk, waist, vx = series(log, contract.CH_SIM_STATUS, "trunk_height", "waist_height", "forward_velocity")
    _panel(axes[0], "height [m]", "T1_SIM_STATUS", [(t, trunk, "trunk"), (t, waist, "waist")])
    tj, cmd_vx = series(log, contract.CH_JOYSTICK, "vx")
    _panel(axes[1], "v [m/s]", "T1_SIM_STATUS and T1_JOYSTICK",
           [(t, vx, "forward velocity"), (tj, cmd_vx, "joystick vx (step)")])
    tc, mode = series(log, contract.CH_JOINT_CMD, "mode")
    _panel(axes[2], "mode", "T1_JOINT_CMD", [(tc, mode, "mode (step)")])
    if tc.size:
        axes[2].set_yticks(range(len(MODE_NAMES)), MODE_NAMES, fontsize=7)
    ts, late_last, late_p99 = series(log, contract.CH_CONTROLLER_STATUS, "lateness_us_last", "lateness_us_p99")
    _panel(axes[3], "lateness [us]", "T1_CONTROLLER_STATUS", [(ts, late_last, "last"), (ts, late_p99, "p99")])
    tq, q = series(log, contract.CH_JOINT_STATE, "q")
    _, q_des = series(log, contract.CH_JOINT_CMD, "q_des")
    for ax, name in zip(axes[4:], joints):
        j = contract.joint_index(name)
        _panel(ax, f"{name}\n[rad]", "T1_JOINT_STATE and T1_JOINT_CMD",
               [(tq, q[:, j] if tq.size else q, "q"), (tc, q_des[:, j] if tc.size else q_des, "q_des (step)")])
    axes[-1].set_xlabel("sim time [s]")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=90)
    plt.close(fig)
    return out

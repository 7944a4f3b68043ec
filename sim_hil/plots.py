"""Plots a roboticist reads at a glance: trunk height, waist height and forward velocity over time
(the seed's Fig. 5.1), from T1_SIM_STATUS samples."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from sim_hil import config  # noqa: E402


def plot_heights_and_velocity(series: dict[str, dict[str, list[float]]], path: Path, title: str,
                              command_vx: list[tuple[float, float]] | None = None) -> Path:
    """series: label -> {"t": [s], "trunk": [m], "waist": [m], "vx": [m/s]} (one line per label)."""
    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for label, s in series.items():
        axes[0].plot(s["t"], s["trunk"], label=label)
        axes[1].plot(s["t"], s["waist"], label=label)
        axes[2].plot(s["t"], s["vx"], label=label)
    axes[0].axhline(config.FALLEN_TRUNK_HEIGHT_M, color="grey", ls=":", lw=1, label="fallen below")
    axes[1].axhline(config.GETUP_SWITCH_WAIST_HEIGHT_M, color="grey", ls="--", lw=1,
                    label="teacher switch (getup below)")
    if command_vx:
        ts, vs = zip(*command_vx)
        axes[2].step(ts, vs, where="post", color="k", ls="--", lw=1, label="command vx")
    axes[0].set_ylabel("trunk height [m]")
    axes[1].set_ylabel("waist height [m]")
    axes[2].set_ylabel("forward velocity [m/s]")
    axes[2].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    axes[0].set_title(title)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path

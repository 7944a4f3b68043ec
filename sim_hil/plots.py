"""Plots a roboticist reads at a glance: trunk height, waist height and forward velocity over time
(the seed's Fig. 5.1), from T1_SIM_STATUS samples, with the runtime's mode shaded behind them."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from common.events import FALLEN_TRUNK_HEIGHT_M  # noqa: E402
from messages import contract  # noqa: E402

MODE_SHADES = {"PREPARE": "tab:blue", "POLICY": "tab:green", "FAULT": "tab:red", "DAMPING": "tab:grey"}
MODE_SHADE_ALPHA = 0.12


def mode_spans(modes: list[tuple[float, str]], t_end: float) -> list[tuple[float, float, str]]:
    """(start [s], end [s], mode) of each stretch of one mode, from (time, mode) samples in time order."""
    spans: list[tuple[float, float, str]] = []
    for (t, mode), (t_next, _) in zip(modes, modes[1:] + [(t_end, "")]):
        if spans and spans[-1][2] == mode:
            spans[-1] = (spans[-1][0], t_next, mode)
        else:
            spans.append((t, t_next, mode))
    return spans


def plot_heights_and_velocity(series: dict[str, dict[str, list[float]]], path: Path, title: str,
                              command_vx: list[tuple[float, float]] | None = None,
                              side_by_side: bool = False, modes: list[tuple[float, str]] | None = None) -> Path:
    """series: label -> {"t": [s], "trunk": [m], "waist": [m], "vx": [m/s][, "kneel": [bool]]}: one line per label
    in one column, or (side_by_side, as the seed's Fig. 5.1) one column per label on shared axes; where a series
    has "kneel" (the kneel band met in the kneeling posture, common/events), those samples are marked on its trunk
    line. modes: (sim time [s], the runtime's mode) samples, shaded as PREPARE / POLICY / FAULT / DAMPING behind
    every axis."""
    columns = len(series) if side_by_side and series else 1
    fig, grid = plt.subplots(3, columns, figsize=(4 * columns + 2 if columns > 1 else 8, 7), sharex=True,
                             sharey="row", squeeze=False)
    for col, (label, s) in enumerate(series.items()):
        axes = grid[:, col if side_by_side else 0]
        axes[0].plot(s["t"], s["trunk"], label=label)
        kneel = [(t, h) for t, h, k in zip(s["t"], s["trunk"], s.get("kneel", ())) if k]
        if kneel:
            axes[0].plot(*zip(*kneel), ls="none", marker="o", ms=3, color="tab:purple",
                         label="kneeling, ≤ 2.9° off vertical (the kneel band)")
        axes[1].plot(s["t"], s["waist"], label=label)
        axes[2].plot(s["t"], s["vx"], label=label)
        if side_by_side:
            axes[0].set_title(label)
    t_end = max((s["t"][-1] for s in series.values() if s["t"]), default=0.0)
    for axes in grid.T:
        labelled: set[str] = set()
        for start, end, mode in mode_spans(modes or [], t_end):
            for ax in axes:
                ax.axvspan(start, end, color=MODE_SHADES.get(mode, "white"), alpha=MODE_SHADE_ALPHA, lw=0,
                           label=mode if ax is axes[0] and mode in MODE_SHADES and mode not in labelled else None)
            labelled.add(mode)
        axes[0].axhline(FALLEN_TRUNK_HEIGHT_M, color="grey", ls=":", lw=1, label="fallen below")
        axes[1].axhline(contract.WAIST_SWITCH_HEIGHT_M, color="grey", ls="--", lw=1,
                        label="teacher switch (getup below)")
        if command_vx:
            ts, vs = map(list, zip(*command_vx))
            if t_end > ts[-1]:      # the last command holds to the end (a step needs its end point)
                ts, vs = ts + [t_end], vs + [vs[-1]]
            axes[2].step(ts, vs, where="post", color="k", ls="--", lw=1, label="command vx")
        axes[2].set_xlabel("time [s]")
        for ax in axes:
            ax.grid(alpha=0.3)
            ax.legend(loc="upper right", fontsize=8)
    grid[0, 0].set_ylabel("trunk height [m]")
    grid[1, 0].set_ylabel("waist height [m]")
    grid[2, 0].set_ylabel("forward velocity [m/s]")
    if columns > 1:
        fig.suptitle(title)
    else:
        grid[0, 0].set_title(title)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path

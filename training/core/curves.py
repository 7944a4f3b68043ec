"""Learning curves of a training run: one CSV (the record that survives resumes), TensorBoard event files
(tensorboardX) and a PNG plot redrawn from the CSV.

The CSV is long-format (step, wall time, metric, value) so metrics that appear only in some rows
(eval/* every epoch, episode/* every training step) need no fixed header, and a resumed run simply
appends: its step numbers continue from the checkpoint, so the curve continues too.
"""
from __future__ import annotations

import csv
import math
import time
from pathlib import Path
from typing import Mapping

from training.core import plots

CSV_NAME = "metrics.csv"
TENSORBOARD_DIR = "tensorboard"
PNG_NAME = "learning_curve.png"
CSV_FIELDS = ("env_steps", "wall_time_s", "metric", "value")
# Metrics drawn in the PNG, in panel order, when present (first match wins per panel).
PLOT_PANELS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("episode reward", ("eval/episode_reward", "episode/sum_reward", "eval/reward_mean", "reward_mean")),
    ("episode length [control steps]", ("eval/avg_episode_length", "episode/length")),
    ("env-steps/s", ("training/sps", "episode/sps", "SPS")),
    ("success", ("eval/episode_success", "episode/success")),
    ("success from the kneel", ("eval/episode_success_from_kneel",)),
    ("success from fallen", ("eval/episode_success_from_fallen",)),
    ("loss", ("training/policy_loss", "training/total_loss", "actor_loss")),
)


class MetricsLog:
    """Append-only metric sink: CSV + TensorBoard. `log(step, metrics)` takes any scalar-like values."""

    def __init__(self, run_dir, tensorboard: bool = True):
        self.run_dir = Path(run_dir)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self.csv_path = self.run_dir / CSV_NAME
        new_file = not self.csv_path.exists()
        self._csv_file = self.csv_path.open("a", newline="")
        self._csv = csv.writer(self._csv_file)
        if new_file:
            self._csv.writerow(CSV_FIELDS)
        self._writer = None
        if tensorboard:
            from tensorboardX import SummaryWriter  # heavy import: only when a run logs
            self._writer = SummaryWriter(str(self.run_dir / TENSORBOARD_DIR))
        self._t0 = time.monotonic()

    def log(self, step: int, metrics: Mapping[str, object]) -> dict[str, float]:
        """Record every finite scalar of `metrics` at `step` [env steps]; returns what was recorded."""
        recorded = {}
        wall = time.monotonic() - self._t0
        for name, value in sorted(metrics.items()):
            try:
                scalar = float(value)  # jax/numpy 0-d arrays and Python numbers
            except (TypeError, ValueError):
                continue
            if not math.isfinite(scalar):
                continue
            self._csv.writerow((int(step), f"{wall:.3f}", name, repr(scalar)))
            if self._writer is not None:
                self._writer.add_scalar(name, scalar, int(step))
            recorded[name] = scalar
        self._csv_file.flush()
        return recorded

    def close(self):
        self._csv_file.close()
        if self._writer is not None:
            self._writer.close()


def read_curves(csv_path, until_wall_s: float | None = None) -> dict[str, list[tuple[int, float]]]:
    """metric → [(env_steps, value)] sorted by step, from a run's CSV; until_wall_s keeps the rows logged
    within that many seconds of their call's start (one call: the first minutes of a run)."""
    curves: dict[str, list[tuple[int, float]]] = {}
    with Path(csv_path).open(newline="") as f:
        reader = csv.DictReader(f)
        if reader.fieldnames is None or tuple(reader.fieldnames) != CSV_FIELDS:
            raise ValueError(f"{csv_path}: header must be {','.join(CSV_FIELDS)}, got {reader.fieldnames}")
        for row in reader:
            if until_wall_s is not None and float(row["wall_time_s"]) > until_wall_s:
                continue
            curves.setdefault(row["metric"], []).append((int(row["env_steps"]), float(row["value"])))
    for points in curves.values():
        points.sort(key=lambda p: p[0])
    return curves


def plot_curves(csv_path, png_path, title: str = "", until_wall_s: float | None = None) -> Path | None:
    """Redraw the learning-curve PNG from the CSV; None when the CSV holds none of the plotted metrics."""
    curves = read_curves(csv_path, until_wall_s)
    panels = []
    for label, candidates in PLOT_PANELS:
        name = next((c for c in candidates if c in curves), None)
        if name is not None:
            panels.append((label, name))
    if not panels:
        return None
    plt = plots.pyplot()
    fig, axes = plt.subplots(len(panels), 1, figsize=(7, 2.2 * len(panels)), sharex=True, squeeze=False)
    for ax, (label, name) in zip(axes[:, 0], panels):
        steps, values = zip(*curves[name])
        ax.plot(steps, values, marker="." if len(steps) < 50 else None)
        ax.set_ylabel(label)
        ax.set_title(name, fontsize=8, loc="right")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("env steps")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    png_path = Path(png_path)
    fig.savefig(png_path, dpi=100)
    plt.close(fig)
    return png_path

"""The seed's Table 4.3 (thesis §4.9): keyframe getup against the reward-only baseline, ours beside the seed's.

Each metric is per episode, averaged over the seeded fallen starts (training/evaluation/batch.py computes them; the
definitions and names are common/effort.py's, at the 2 ms physics step). The seed gives no
definitions and ran IsaacGym on its own model, so absolute values need not agree; what can be compared is
the direction: whether the keyframe policy is below or above the baseline in both studies. The ratio
keyframe / baseline is unit-free, so one bar plot shows every metric for both studies.

The seed does not define "Z Contact Force (Total)"; ours is the episode's vertical impulse from the
ground on the robot, Σ_t |F_z|·dt [N·s] (its magnitude is of the order of the seed's figure: the weight
over a 10 s episode).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from common.seed_figures import SEED_TABLE_4_3
from training.core import plots

# summary key (training/evaluation/batch.py) -> the seed's Table 4.3 row, in the seed's order
SEED_METRIC = {"energy_J": "Average Energy Sum", "max_torque_Nm": "Average Max Torques",
               "max_joint_acc_radps2": "Average Max Joint Acceleration",
               "total_joint_acc_radps": "Total Joint Acceleration", "total_torque_Nms": "Total Torques",
               "mean_contact_force_N": "Average Contact Force", "z_contact_impulse_Ns": "Z Contact Force (Total)",
               "max_energy_J": "Average Max Energy"}
# the evaluation's roles: "policy" is the keyframe getup, "baseline" the reward-only one
SEED_REPORTED = {key: {"policy": SEED_TABLE_4_3[m][1], "baseline": SEED_TABLE_4_3[m][0]}
                 for key, m in SEED_METRIC.items()}


def ratios(summaries: dict) -> dict[str, tuple[float, float]]:
    """{summary key: (ours keyframe/baseline, seed's keyframe/baseline)}; needs both roles."""
    out = {}
    for key, seed in SEED_REPORTED.items():
        ours_policy, ours_base = summaries["policy"][key], summaries["baseline"][key]
        ours = ours_policy / ours_base if ours_base and not math.isnan(ours_base) else math.nan
        out[key] = (ours, seed["policy"] / seed["baseline"])
    return out


def direction_rows(summaries: dict) -> list[str]:
    """Markdown: per metric, ours policy/baseline beside the seed's keyframe/baseline, and whether the
    directions agree (the seed's comparison where the policy is a keyframe getup)."""
    lines = ["| Table 4.3 metric | ours: policy / baseline | seed: keyframe / baseline | same direction |",
             "|---|---|---|---|"]
    for key, (ours, seed) in ratios(summaries).items():
        agree = "n/a" if math.isnan(ours) else ("yes" if (ours < 1) == (seed < 1) else "**no**")
        ours_s = "n/a" if math.isnan(ours) else f"{ours:.2f}"
        lines.append(f"| {SEED_METRIC[key]} | {ours_s} | {seed:.2f} | {agree} |")
    return lines


def plot_ratios(summaries: dict, png: Path) -> None:
    """Grouped bars of keyframe/baseline per metric, ours and the seed's; 1 = equal effort."""
    plt = plots.pyplot()
    r = ratios(summaries)
    x = np.arange(len(r))
    fig, ax = plt.subplots(figsize=(10, 4.5))
    ax.bar(x - 0.2, [v[0] for v in r.values()], 0.4, label="ours: policy / baseline")
    ax.bar(x + 0.2, [v[1] for v in r.values()], 0.4, label="seed (Table 4.3)")
    ax.axhline(1.0, color="k", linewidth=0.8)
    ax.set_xticks(x, [SEED_METRIC[k].replace("Average ", "avg ") for k in r], rotation=25, ha="right")
    ax.set_ylabel("policy / baseline (seed: keyframe / baseline)")
    ax.set_title("Getup effort relative to the baseline (< 1: lower than the baseline)")
    ax.legend()
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(png, dpi=100)
    plt.close(fig)

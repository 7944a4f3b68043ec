"""The seed's published figures, to print beside ours. Each entry: table row -> (value, source).

Only figures we were actually given are filled, each with where it came from: the seed's Table 4.3
(all eight metrics, from the thesis) and the seed's headline results quoted by the project issues as targets (100 % getup success; push attempts ≤ 1.1 mean and ≤ 2 max; all 5 wall runs
completed; every puddle slip recovered). Every other cell prints "unknown (seed figure not available)".
Fill a value ONLY with its source.
"""
from __future__ import annotations

UNKNOWN = (None, "seed figure not available to us")
# Seed thesis Table 4.3 (../shared/seed/thesis.txt §4.9), averaged over 1000 seeds: metric -> (baseline,
# keyframe). The seed gives no units; the values are printed beside ours as the seed's, not converted.
SEED_TABLE_4_3: dict[str, tuple[float, float]] = {
    "Average Energy Sum": (2279.839, 1604.966),
    "Average Max Torques": (438.703, 420.283),
    "Average Max Joint Acceleration": (425.661, 301.457),
    "Total Joint Acceleration": (1797.189, 1313.935),
    "Total Torques": (37386.540, 39763.719),
    "Average Contact Force": (449.743, 857.012),
    "Z Contact Force (Total)": (4768.910, 4714.383),
    "Average Max Energy": (96.558, 80.327),
}
SEED_ENERGY_SUM_J = {"policy": SEED_TABLE_4_3["Average Energy Sum"][1],
                     "baseline": SEED_TABLE_4_3["Average Energy Sum"][0]}
_TABLE_4_3 = "seed Table 4.3 (thesis §4.9)"


def _table_4_3(metric: str) -> tuple[str, str]:
    baseline, keyframe = SEED_TABLE_4_3[metric]
    return f"{keyframe} keyframe / {baseline} baseline ('{metric}')", _TABLE_4_3
_ISSUE_TARGET = "seed result, quoted as a target in the project's student issue"

# scenario -> {row label as in sim_hil/eval/plans.py: (value or None, where it comes from)}
SEED_FIGURES: dict[str, dict[str, tuple[str | None, str]]] = {
    "getup": {
        "success rate": ("100 %", _ISSUE_TARGET),
        "energy Σ|τ·q̇|·dt [J]": _table_4_3("Average Energy Sum"),
        "max energy per tick [J]": _table_4_3("Average Max Energy"),
        "max torque [N·m]": _table_4_3("Average Max Torques"),
        "total torque Σ|τ|·dt [N·m·s]": _table_4_3("Total Torques"),
        "max joint acc [rad/s²]": _table_4_3("Average Max Joint Acceleration"),
        "total joint acc Σ|q̈|·dt [rad/s]": _table_4_3("Total Joint Acceleration"),
        "contact force mean [N]": _table_4_3("Average Contact Force"),
    },
    "push": {
        "forward: attempts mean / max / min / std": ("≤ 1.1 mean, ≤ 2 max", _ISSUE_TARGET),
        "backward: attempts mean / max / min / std": ("≤ 1.1 mean, ≤ 2 max", _ISSUE_TARGET),
    },
    "wall": {"DNF": ("0/5", _ISSUE_TARGET)},
    "puddle": {"up at the end": ("every slip recovered", _ISSUE_TARGET)},
}


def seed_figure(scenario: str, row: str) -> str:
    value, source = SEED_FIGURES.get(scenario, {}).get(row, UNKNOWN)
    return f"{value} ({source})" if value is not None else f"unknown ({source})"

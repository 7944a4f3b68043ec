"""The seed's published figures, to print beside ours. Each entry: table row -> (value, source).

Only figures we were actually given are filled, each with where it came from: the project issues quote
the seed's Table 4.3 energy sums (keyframe getup 1605.0, reward-only baseline 2279.8) and the seed's
headline results as targets (100 % getup success; push attempts ≤ 1.1 mean and ≤ 2 max; all 5 wall runs
completed; every puddle slip recovered). Every other cell prints "unknown (seed figure not available)".
Fill a value ONLY with its source.
"""
from __future__ import annotations

UNKNOWN = (None, "seed figure not available to us")
# Seed Table 4.3 energy sums over a getup [J]: keyframe-curriculum policy vs reward-only baseline (quoted in
# the project's baseline issue). The MJX evaluator (training/evaluate.py) prints these too.
SEED_ENERGY_SUM_J = {"policy": 1605.0, "baseline": 2279.8}
_ISSUE_TARGET = "seed result, quoted as a target in the project's student issue"

# scenario -> {row label as in sim_hil/eval/plans.py: (value or None, where it comes from)}
SEED_FIGURES: dict[str, dict[str, tuple[str | None, str]]] = {
    "getup": {
        "success rate": ("100 %", _ISSUE_TARGET),
        "energy Σ|τ·q̇|·dt [J]": (f"{SEED_ENERGY_SUM_J['policy']} keyframe / {SEED_ENERGY_SUM_J['baseline']} baseline",
                                   "seed Table 4.3, quoted in the project's baseline issue"),
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

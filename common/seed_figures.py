"""The seed thesis's published figures (../shared/seed/thesis.txt §4.9 and chapter 6), printed beside ours.

Two kinds: summary figures per report row (`SEED_FIGURES`: scenario -> our row label -> the seed's
DAgger-100k student and baseline composite values, with the table they come from), and the seed's
per-trial tables verbatim (`SEED_TRIAL_TABLES`). Values are as the seed prints them; where the seed's
summary and its own per-trial table disagree (Table 6.5 vs 6.6) both are given. A figure the seed does
not give is None and prints "not in the seed". A value derived from a seed table says so.
"""
from __future__ import annotations

from dataclasses import dataclass

from common.effort import EFFORT_METRICS

# Seed thesis Table 4.3 (§4.9), averaged over 1000 seeds: metric -> (baseline, keyframe). The seed gives no
# units; the values are printed beside ours as the seed's, not converted.
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


@dataclass(frozen=True)
class SeedFigure:
    student: str | None     # the seed's DAgger-100k (getup: its keyframe expert, Table 4.3)
    baseline: str | None    # the seed's baseline composite (getup: its baseline getup policy)
    source: str


# column headers of the two seed columns, per scenario
SEED_COLUMNS = {"getup": ("seed: keyframe expert", "seed: baseline getup")}
DEFAULT_SEED_COLUMNS = ("seed: DAgger-100k", "seed: baseline")


def _t43(metric: str) -> SeedFigure:
    baseline, keyframe = SEED_TABLE_4_3[metric]
    return SeedFigure(f"{keyframe}", f"{baseline}", f"Table 4.3 '{metric}'")


_EFFORT_LABEL = {key: label for key, label, _ in EFFORT_METRICS}   # the report rows of Table 4.3's metrics
_PUSH_F = "Table 6.5; Table 6.6's per-trial lists give means 1.15 and 3.45"
_PUSH_B = "Table 6.7; std computed from Table 6.8"
SEED_FIGURES: dict[str, dict[str, SeedFigure]] = {
    "getup": {
        "success rate": SeedFigure("100 %", None, "the project's target (every getup of the seed's ch. 6 succeeded)"),
        _EFFORT_LABEL["energy_J"]: _t43("Average Energy Sum"),
        _EFFORT_LABEL["max_energy_J"]: _t43("Average Max Energy"),
        _EFFORT_LABEL["max_torque_Nm"]: _t43("Average Max Torques"),
        _EFFORT_LABEL["total_torque_Nms"]: _t43("Total Torques"),
        _EFFORT_LABEL["max_joint_acc_radps2"]: _t43("Average Max Joint Acceleration"),
        _EFFORT_LABEL["total_joint_acc_radps"]: _t43("Total Joint Acceleration"),
        _EFFORT_LABEL["mean_contact_force_N"]: _t43("Average Contact Force"),
    },
    "push": {
        "forward: trials": SeedFigure("20", "20", "Table 6.5"),
        "forward: attempts mean / max / min / std": SeedFigure("1.16 / 2 / 1 / 0.37", "3.65 / 11 / 1 / 2.37", _PUSH_F),
        "forward: fell": SeedFigure("20/20", "20/20", "§6 push: a forward fall in every trial"),
        "forward: up at the end": SeedFigure("20/20", "20/20", "§6 push: both recovered in all 20 trials"),
        "backward: trials": SeedFigure("10", "10", "Table 6.7"),
        "backward: attempts mean / max / min / std": SeedFigure("1.1 / 2 / 1 / 0.30", "1.9 / 4 / 1 / 0.94", _PUSH_B),
        "backward: fell": SeedFigure("10/10", "10/10", "§6 push: a backward fall in every trial"),
        "backward: up at the end": SeedFigure("10/10", "10/10", "§6 push: both recovered in all 10 trials"),
        "backward: ran to stabilise": SeedFigure("0/10", "3/10", "Table 6.7"),
    },
    "wall": {
        "completion time [s]": SeedFigure("37.8", "35.25 (the 4 that finished)", "Tables 6.1, 6.2"),
        "DNF": SeedFigure("0/5", "1/5", "Tables 6.1, 6.2"),
        "getup attempts per wall": SeedFigure("1.26", "2.5", "Tables 6.1, 6.2 'Avg. Attempts per Wall'"),
        "getup attempts per trial": SeedFigure("3.8", "7.0", "mean of Tables 6.1, 6.2 'Getup Attempts (Total)'"),
    },
    "puddle": {
        "trials with a slip": SeedFigure("3/10", "2/10", "Tables 6.3, 6.4"),
        "getup attempts per trial": SeedFigure("0.50", "0.50", "Tables 6.3, 6.4: 1 + 1 + 3 and 3 + 2 over 10 trials"),
        "up at the end": SeedFigure("10/10", "10/10", "§6 puddle: every slip recovered"),
    },
}


@dataclass(frozen=True)
class SeedTrialTable:
    title: str
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    note: str = ""


def _attempts(policy: str, attempts: str) -> tuple[str, ...]:
    return (policy, *attempts.split())


SEED_TRIAL_TABLES: dict[str, tuple[SeedTrialTable, ...]] = {
    "wall": (
        SeedTrialTable("Table 6.1: DAgger-100k", ("trial", "completion time [s]", "getup attempts (total)",
                                                  "avg. attempts per wall"),
                       (("1", "38", "3", "1.00"), ("2", "38", "5", "1.67"), ("3", "38", "4", "1.33"),
                        ("4", "37", "4", "1.33"), ("5", "38", "3", "1.00"), ("average", "37.8", "—", "1.26"))),
        SeedTrialTable("Table 6.2: baseline", ("trial", "completion time [s]", "getup attempts (total)",
                                               "avg. attempts per wall"),
                       (("1", "37", "4", "1.33"), ("2", "33", "5", "1.67"), ("3", "DNF", "12", "—"),
                        ("4", "34", "7", "2.33"), ("5", "37", "7", "2.33"), ("average", "35.25", "—", "2.5")),
                       "In trial 3 the 12 attempts are at the first two walls, from which it recovered."),
    ),
    "puddle": (
        SeedTrialTable("Table 6.3: DAgger-100k", ("trial", "slipped?", "getup attempts"),
                       (("2", "yes", "1"), ("3", "yes", "1"), ("8", "yes", "3"), ("others", "no", "—"))),
        SeedTrialTable("Table 6.4: baseline", ("trial", "slipped?", "getup attempts"),
                       (("6", "yes", "3"), ("10", "yes", "2"), ("others", "no", "—"))),
    ),
    "push": (
        SeedTrialTable("Table 6.6: forward pushes, getup attempts per trial", ("policy", *map(str, range(1, 21))),
                       (_attempts("baseline", "2 5 1 11 4 10 1 2 3 2 2 2 5 2 3 3 3 1 3 4"),
                        _attempts("DAgger-100k", "1 1 1 1 1 1 1 1 1 1 2 1 1 2 1 1 2 1 1 1"))),
        SeedTrialTable("Table 6.8: backward pushes, getup attempts per trial", ("policy", *map(str, range(1, 11))),
                       (_attempts("baseline", "1 4 2 2 1 2 3 1 1 2"),
                        _attempts("DAgger-100k", "1 1 1 1 2 1 1 1 1 1"))),
    ),
}


def seed_columns(scenario: str) -> tuple[str, str]:
    return SEED_COLUMNS.get(scenario, DEFAULT_SEED_COLUMNS)


def seed_cells(scenario: str, row: str) -> tuple[str, str]:
    """(student, baseline) cells of one report row: 'value (source)', or 'not in the seed'."""
    fig = SEED_FIGURES.get(scenario, {}).get(row)
    if fig is None:
        return "not in the seed", "not in the seed"
    return tuple(f"{v} ({fig.source})" if v is not None else "not in the seed" for v in (fig.student, fig.baseline))

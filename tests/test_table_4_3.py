"""The Table 4.3 comparison (training/evaluation/table_4_3.py): ratios, direction against the seed, the bar plot."""
import math

from training.evaluation import table_4_3


def _summaries(policy_scale: float) -> dict:
    base = {key: 100.0 for key in table_4_3.SEED_METRIC}
    return {"policy": {k: v * policy_scale for k, v in base.items()}, "baseline": base}


def test_ratio_is_keyframe_over_baseline_beside_the_seeds():
    r = table_4_3.ratios(_summaries(0.7))
    assert math.isclose(r["energy_J"][0], 0.7)
    assert math.isclose(r["energy_J"][1], 1604.966 / 2279.839)


def test_direction_is_compared_per_metric():
    # the seed's keyframe is lower on every metric but total torque and mean contact force
    rows = "\n".join(table_4_3.direction_rows(_summaries(0.7)))
    assert "| Average Energy Sum | 0.70 | 0.70 | yes |" in rows
    assert "| Total Torques | 0.70 | 1.06 | **no** |" in rows
    assert "| Average Contact Force | 0.70 | 1.91 | **no** |" in rows


def test_a_missing_baseline_value_is_not_a_direction():
    s = _summaries(0.7)
    s["baseline"]["energy_J"] = math.nan
    assert "| Average Energy Sum | n/a | 0.70 | n/a |" in "\n".join(table_4_3.direction_rows(s))


def test_bar_plot_is_written(tmp_path):
    table_4_3.plot_ratios(_summaries(1.2), tmp_path / "t.png")
    assert (tmp_path / "t.png").stat().st_size > 0

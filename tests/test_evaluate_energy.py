"""The getup evaluation's energy until the first stand-up (training/evaluation/batch.py episode_row) and its
seed-paired ratio: the getup's own energy, apart from the standing that follows it."""
import math

import numpy as np

from training.evaluation.batch import episode_row, paired_energy_to_stand

DT = 0.02       # [s] control tick
TICKS = 500     # 10 s


def _episode(stand_at_s: float | None, joules_per_tick: float = 1.0):
    """A fallen start (trunk 0.2 m, lying) that stands (trunk 0.66 m, upright) from stand_at_s on."""
    t = np.arange(TICKS + 1) * DT
    up = np.zeros(TICKS + 1) if stand_at_s is None else (t >= stand_at_s).astype(float)
    readings = np.stack([0.2 + 0.46 * up, 0.1 + 0.9 * up, 0.15 + 0.55 * up], axis=1)
    zeros = np.zeros(TICKS)
    series = {"energy_J": np.full(TICKS, joules_per_tick), "max_energy_J": zeros, "max_torque_Nm": zeros,
              "torque_integral": zeros, "max_qacc": zeros, "qacc_integral": zeros,
              "contact_force_N": zeros, "contact_force_z_N": zeros}
    return t, readings, series


def test_energy_until_the_first_stand_up_counts_only_the_ticks_before_it():
    row = episode_row(*_episode(stand_at_s=2.0))
    assert row["success"] and math.isclose(row["time_to_stand_s"], 2.0)
    assert math.isclose(row["energy_to_stand_J"], 2.0 / DT)        # 100 ticks of 1 J
    assert math.isclose(row["energy_J"], TICKS)                    # the whole episode


def test_an_episode_that_never_stood_has_no_energy_until_standing():
    row = episode_row(*_episode(stand_at_s=None))
    assert not row["success"] and math.isnan(row["energy_to_stand_J"])


def test_the_paired_ratio_uses_only_seeds_where_both_stood():
    policy = [episode_row(*_episode(1.0)), episode_row(*_episode(None)), episode_row(*_episode(2.0))]
    baseline = [episode_row(*_episode(2.0)), episode_row(*_episode(1.0)), episode_row(*_episode(None))]
    ratio, both = paired_energy_to_stand(policy, baseline)
    assert both == 1 and math.isclose(ratio, 0.5)
    ratio, both = paired_energy_to_stand(policy[1:2], baseline[2:3])
    assert both == 0 and math.isnan(ratio)


def test_attempts_per_fall_counts_a_mid_fall_start_once():
    """A bank's mid-fall start (trunk still above the fallen height) is down only once it lands: that landing
    is its one down phase, so one attempt that stands is 1.0 attempts per fall, as for a fallen start."""
    from training.evaluation.batch import summarize
    t, readings, series = _episode(stand_at_s=2.0)
    readings[:10, 0] = 0.45                                   # the hand-over tick, then landing at 0.2 m
    mid_fall = episode_row(t, readings, series)
    fallen = episode_row(*_episode(stand_at_s=2.0))
    assert mid_fall["falls"] == 1 and mid_fall["down_phases"] == 1 and fallen["down_phases"] == 1
    summary = summarize([mid_fall, fallen])
    assert summary["attempts_per_fall"] == 1.0 and summary["attempts_per_episode"] == 1.0
    assert summary["max_attempts"] == 1


def test_the_kneel_figures_come_from_the_posture_column_and_are_nan_without_it():
    t, readings, series = _episode(stand_at_s=None)
    readings[100:200, 0], readings[100:200, 1] = 0.41, 1.0          # 2 s at the gate's height, upright
    kneeling = np.zeros((len(t), 1))
    kneeling[100:130] = 1.0                                          # of which 0.6 s kneeling
    row = episode_row(t, np.concatenate([readings, kneeling], axis=1), series)
    assert row["kneeled"] == 1.0 and math.isclose(row["kneel_hold_s"], 0.6) and row["kneel_held"] == 0.0
    kneeling[100:160] = 1.0
    assert episode_row(t, np.concatenate([readings, kneeling], axis=1), series)["kneel_held"] == 1.0
    assert math.isnan(episode_row(t, readings, series)["kneeled"])


def test_a_kneel_runs_seen_seeds_are_its_fallen_bank_and_its_demonstrations_starts(tmp_path):
    from training.ppo.kneel_report import seen_seeds
    for seed in (3, 40):
        (tmp_path / f"demo_{seed}.npz").write_bytes(b"")
    env = {"fallen": {"seed": 1000, "bank_starts": 3}, "demo_starts": {"prob": 0.0, "folder": str(tmp_path)}}
    assert seen_seeds({"env_config": env}) == {1000, 1001, 1002}
    env["demo_starts"]["prob"] = 0.5
    assert seen_seeds({"env_config": env}) == {3, 40, 1000, 1001, 1002}

"""Table 4.3's effort metrics have one definition and one set of names (common/effort.py): the loop's evaluation
(sim_hil/eval/metrics.py, per-tick rates) and the batch's (training/evaluation/batch.py, per-tick integrals)
compute the same figures under the same keys, and both reports label them alike."""
from __future__ import annotations

import math

import numpy as np

from common.effort import EFFORT_KEYS, EFFORT_METRICS, effort_metrics
from common.model import load_model
from sim_hil import config
from sim_hil.eval import metrics
from training.evaluation import batch

TICKS = 50
RNG = np.random.default_rng(3)
POWER_W, TAU_MAX_NM, TAU_SUM_NM, QACC_MAX, QACC_SUM, CONTACT_N = (RNG.uniform(0, 100, TICKS) for _ in range(6))


def test_the_definitions():
    dt = config.LOOP_PERIOD_S
    e = effort_metrics(POWER_W, POWER_W, TAU_MAX_NM, TAU_SUM_NM, QACC_MAX, QACC_SUM, CONTACT_N, dt_s=dt)
    assert tuple(e) == EFFORT_KEYS
    assert math.isclose(e["energy_J"], POWER_W.sum() * dt) and math.isclose(e["max_energy_J"], POWER_W.max() * dt)
    assert e["max_torque_Nm"] == TAU_MAX_NM.max() and math.isclose(e["total_torque_Nms"], TAU_SUM_NM.sum() * dt)
    assert e["max_joint_acc_radps2"] == QACC_MAX.max()
    assert math.isclose(e["total_joint_acc_radps"], QACC_SUM.sum() * dt)
    assert e["max_contact_force_N"] == CONTACT_N.max() and math.isclose(e["mean_contact_force_N"], CONTACT_N.mean())


def test_the_loop_and_the_batch_give_the_same_figures_under_the_same_names():
    dt = config.LOOP_PERIOD_S
    log = metrics.TickLog(load_model(), TICKS)
    log.power[:], log.tau_max[:], log.tau_sum[:] = POWER_W, TAU_MAX_NM, TAU_SUM_NM
    log.qacc_max[:], log.qacc_sum[:], log.contact_n[:] = QACC_MAX, QACC_SUM, CONTACT_N
    loop = metrics.effort_metrics(log, 0, TICKS)
    t = np.arange(TICKS + 1) * dt
    readings = np.tile([0.2, 0.1, 0.15], (TICKS + 1, 1))           # lying all along
    series = {"energy_J": POWER_W * dt, "max_energy_J": POWER_W * dt, "max_torque_Nm": TAU_MAX_NM,
              "torque_integral": TAU_SUM_NM * dt, "max_qacc": QACC_MAX, "qacc_integral": QACC_SUM * dt,
              "contact_force_N": CONTACT_N, "contact_force_z_N": CONTACT_N}
    row = batch.episode_row(t, readings, series)
    assert tuple(loop) == EFFORT_KEYS and set(EFFORT_KEYS) <= set(row) and set(EFFORT_KEYS) <= set(batch.EFFORT_KEYS)
    for key in EFFORT_KEYS:
        assert math.isclose(loop[key], row[key], rel_tol=1e-12), key


def test_both_reports_use_the_one_labels():
    from sim_hil.eval import plans
    row = plans.getup_rows([])
    batch_labels = {key: label for label, key, _ in batch.ROWS}
    for key, label, _ in EFFORT_METRICS:
        assert label in row, label
        assert batch_labels[key].replace("\\|", "|") == label, key

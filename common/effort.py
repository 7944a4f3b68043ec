"""The seed's Table 4.3 effort metrics: one definition and one set of names (units in the names), which the loop's
evaluation (sim_hil/eval/metrics.py, per 2 ms control tick) and the batch evaluation (training/evaluation/batch.py,
per physics substep summed into each control tick) both compute, report and store.

Over an episode's ticks k (each a series of per-tick values, scaled by `dt_s` where a sum or a tick's energy is an
integral over time: the loop's per-tick rates use the tick, the batch's per-tick integrals come already in units):
    energy_J              Σ_k Σ_j |τ·q̇|·dt       mechanical work of the motors, both signs counted
    max_energy_J          max_k of one step's Σ_j |τ·q̇|·dt   (largest energy of one physics step; / dt = peak power)
    max_torque_Nm         max_k,j |τ|
    total_torque_Nms      Σ_k Σ_j |τ|·dt
    max_joint_acc_radps2  max_k,j |q̈|
    total_joint_acc_radps Σ_k Σ_j |q̈|·dt
    max_contact_force_N   max_k of the total normal force of the robot's contacts with the world
    mean_contact_force_N  its mean over the ticks
"""
from __future__ import annotations

import numpy as np

# (key, report label, format) in Table 4.3's order of ours; the keys are what results.json / per_env.csv hold
EFFORT_METRICS: tuple[tuple[str, str, str], ...] = (
    ("energy_J", "energy Σ|τ·q̇|·dt [J]", "{:.1f}"),
    ("max_energy_J", "max energy in one physics step [J]", "{:.2f}"),
    ("max_torque_Nm", "max torque [N·m]", "{:.1f}"),
    ("total_torque_Nms", "total torque Σ|τ|·dt [N·m·s]", "{:.0f}"),
    ("max_joint_acc_radps2", "max joint acc [rad/s²]", "{:.0f}"),
    ("total_joint_acc_radps", "total joint acc Σ|q̈|·dt [rad/s]", "{:.0f}"),
    ("max_contact_force_N", "max contact force [N]", "{:.0f}"),
    ("mean_contact_force_N", "mean contact force [N]", "{:.0f}"),
)
EFFORT_KEYS: tuple[str, ...] = tuple(key for key, _, _ in EFFORT_METRICS)


def effort_metrics(power, max_power, max_torque_nm, torque_sum_nm, max_joint_acc_radps2, joint_acc_sum_radps2,
                   contact_force_n, dt_s: float = 1.0) -> dict[str, float]:
    """Table 4.3 over one episode's ticks from per-tick series (each (T,)): power Σ_j |τ·q̇| and the largest of one
    physics step's max_power in the tick, |τ| max and Σ_j, |q̈| max and Σ_j, the total contact normal force [N].
    dt_s turns a rate into its integral over a tick: the tick's length [s] for per-tick rates, 1 where the series
    already are integrals over the tick ([J], [N·m·s], [rad/s])."""
    return {
        "energy_J": float(np.sum(power) * dt_s),
        "max_energy_J": float(np.max(max_power) * dt_s),
        "max_torque_Nm": float(np.max(max_torque_nm)),
        "total_torque_Nms": float(np.sum(torque_sum_nm) * dt_s),
        "max_joint_acc_radps2": float(np.max(max_joint_acc_radps2)),
        "total_joint_acc_radps": float(np.sum(joint_acc_sum_radps2) * dt_s),
        "max_contact_force_N": float(np.max(contact_force_n)),
        "mean_contact_force_N": float(np.mean(contact_force_n)),
    }

"""Lockstep real-time factor of the full-collision simulated T1 with a scripted client in the loop
(separate process, over LCM, through the emulated CAN buses), standing and fallen, next to the bare
physics of the same model stepped in this process (the ceiling the bus and LCM overhead is measured
against). Target: >= 10x real time."""
from __future__ import annotations

import time

import mujoco

from sim_hil import model as t1model
from tests.sim_harness import hold_pose, run_with_client

SIM_SECONDS = 5.0


def physics_only_rtf(spawn: str, seconds: float = SIM_SECONDS) -> float:
    model, _ = t1model.build_model("flat", 0)
    data = mujoco.MjData(model)
    kind, _, seed = spawn.partition(":")
    data.qpos[:], data.qvel[:] = t1model.spawn_state(model, kind, int(seed or 0))
    kp, kd = t1model.pd_gains(model)
    limits = t1model.torque_limits(model)
    target = data.qpos[7:].copy()
    n = int(seconds / model.opt.timestep)
    start = time.perf_counter()
    for _ in range(n):
        data.ctrl[:] = (kp * (target - data.qpos[7:]) - kd * data.qvel[6:]).clip(-limits, limits)
        mujoco.mj_step(model, data)
    return seconds / (time.perf_counter() - start)


def hil_rtf(spawn: str, seconds: float = SIM_SECONDS) -> float:
    model, _ = t1model.build_model("flat", 0)
    kp, kd = t1model.pd_gains(model)
    kind, _, seed = spawn.partition(":")
    q0, _ = t1model.spawn_state(model, kind, int(seed or 0))
    client, _, _ = run_with_client(["--clock", "lockstep", "--spawn", spawn], hold_pose(q0[7:]), kp, kd,
                                   duration_s=seconds, timeout_s=600)
    sim_s = (len(client.wall) - 1) * 0.002
    return sim_s / (client.wall[-1] - client.wall[0])


def main() -> None:
    print(f"== sim_hil lockstep real-time factor ({SIM_SECONDS:g} s of sim time each; target >= 10x) ==")
    print(f"{'spawn':<12}{'HIL lockstep RTF':>18}{'physics-only RTF':>18}{'HIL/physics':>13}")
    for spawn in ("standing", "fallen:3"):
        hil, phys = hil_rtf(spawn), physics_only_rtf(spawn)
        print(f"{spawn:<12}{hil:>17.1f}x{phys:>17.1f}x{hil / phys:>13.2f}")

"""Lockstep real-time factor of the full-collision simulated T1 with the C++ runtime in the loop (separate
process, over LCM, through the emulated CAN buses and the firmware motors), standing and fallen; next to
the same with every tick in Python (--python-tick) and with the python-can buses as well (--can-interface
virtual: the simulator before its C host link), with a scripted Python client, and the bare physics of the same
model stepped in this process (the ceiling the bus and LCM overhead is measured against). Target: >= 10x."""
from __future__ import annotations

import time

import lcm
import mujoco
from t1 import sim_status_t

from common import model as t1model
from common import scenarios
from messages import contract
from sim_hil.launch import ROOT, start_runtime, start_sim, stop, wait_until_listening
from tests.sim_harness import hold_pose, run_with_client

SIM_SECONDS = 5.0


def physics_only_rtf(spawn: str, seconds: float = SIM_SECONDS) -> float:
    model, _ = scenarios.build("flat", 0)
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
    model, _ = scenarios.build("flat", 0)
    kp, kd = t1model.pd_gains(model)
    kind, _, seed = spawn.partition(":")
    q0, _ = t1model.spawn_state(model, kind, int(seed or 0))
    client, _, _ = run_with_client(["--clock", "lockstep", "--spawn", spawn], hold_pose(q0[7:]), kp, kd,
                                   duration_s=seconds, timeout_s=600)
    sim_s = (len(client.wall) - 1) * 0.002
    return sim_s / (client.wall[-1] - client.wall[0])


def runtime_hil_rtf(spawn: str, seconds: float = SIM_SECONDS, *sim_args: str) -> float:
    """The deployment loop: the C++ runtime (untrained student, POLICY mode) answers every state. Timed from
    the sim's status messages (10 Hz of sim time): a subscriber to every state would load the CPU it measures."""
    lc = lcm.LCM(contract.lcm_url())
    marks: list[tuple[float, int]] = []     # (wall [s], sim time [µs]) of each T1_SIM_STATUS
    lc.subscribe(contract.CH_SIM_STATUS,
                 lambda _c, d: marks.append((time.perf_counter(), sim_status_t.decode(d).utime)))
    runtime = start_runtime(ROOT / "policies" / "student_untrained" / "student_untrained.safetensors",
                            "--clock", "lockstep", "--autostart")
    wait_until_listening(runtime)
    sim = start_sim("--clock", "lockstep", "--spawn", spawn, "--duration", str(seconds), *sim_args)
    while sim.poll() is None:
        lc.handle_timeout(20)
    stop(runtime)
    (wall0, sim0), (wall1, sim1) = marks[0], marks[-1]
    return (sim1 - sim0) * 1e-6 / (wall1 - wall0)


TARGET_RTF = 10.0


def main() -> None:
    print(f"== sim_hil lockstep real-time factor ({SIM_SECONDS:g} s of sim time each; target >= {TARGET_RTF:g}x) ==")
    print(f"{'spawn':<12}{'+ C++ runtime':>15}{'/ target':>10}{'Python tick':>13}{'/ it':>7}{'+ python-can':>14}"
          f"{'/ it':>7}{'+ Py client':>13}{'physics only':>14}{'/ it':>7}")
    for spawn in ("standing", "fallen:3"):
        rt = runtime_hil_rtf(spawn)
        py = runtime_hil_rtf(spawn, SIM_SECONDS, "--python-tick")
        pycan = runtime_hil_rtf(spawn, SIM_SECONDS, "--python-tick", "--can-interface", "virtual")
        hil, phys = hil_rtf(spawn), physics_only_rtf(spawn)
        print(f"{spawn:<12}{rt:>14.1f}x{rt / TARGET_RTF:>10.2f}{py:>12.1f}x{rt / py:>7.2f}{pycan:>13.1f}x"
              f"{rt / pycan:>7.2f}{hil:>12.1f}x{phys:>13.1f}x{rt / phys:>7.2f}")
    print("(C++ runtime: t1-runtime, untrained student, answers every state; Python tick: the same with "
          "--python-tick; + python-can: and --can-interface virtual; Py client: scripted PD client, a separate "
          "Python process; physics only: mj_step + PD in this process, no bus, no LCM: the ceiling; / it: the "
          "C++-tick figure over the column's)")

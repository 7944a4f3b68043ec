"""The getup evaluation's rollout on the CPU backend (MuJoCo C), the same series as evaluate.make_rollout.

evaluation/batch.py's MJX rollout aggregates per physics substep inside one jitted scan. Here the C batch steps one
substep per call (firmware_like's motor step as MuJoCo's control callback, as in training), the policy runs
jitted once per control tick, and the host aggregates exactly what the MJX rollout does:
  energy Σ|τ·q̇₀|·dt_sim [J] (q̇₀: joint velocity at the substep's start, τ: the torque applied over it) and
  its largest single substep, max |τ| [N·m], Σ|τ|·dt_sim [N·m·s], max |q̈| [rad/s²], Σ|q̈|·dt_sim [rad/s] per
  tick, and after the tick's last substep the total normal and world-z force of the robot's penetrating
  contacts with the world [N] (MuJoCo's mj_contactForce; MJX: contact_force_dim).
A persistent batch keeps each simulation's whole MjData, so the contacts and constraint forces read after
a tick are those of its last substep's start, as mjx.Data's are after mjx.step.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from common import events
from common import observation as obsdef
from training.envs.cpu_backend import HostData


def cpu_rollout(env, policy, qpos: np.ndarray, qvel: np.ndarray, num_ticks: int, keep_qpos: bool = False,
                target_noise_rad: float = 0.0, noise_seed: int = 0) -> dict:
    """(N,) fallen starts → dict of numpy series: readings (N, T + 1, 4) [trunk, up_z, waist, kneeling posture
    (common/events.py: 1 or 0)], and per tick
    (N, T): energy_J, max_energy_J, max_torque_Nm, torque_integral, max_qacc, qacc_integral,
    contact_force_N, contact_force_z_N; with keep_qpos also qpos (N, T + 1, nq) at each reading (to look at
    or render the rollout afterwards). target_noise_rad > 0: every joint target of every tick gets N(0, σ²) [rad]
    (seeded by noise_seed) before the supervisor's rules, as a PPO policy's sampled actions move them: whether a
    behaviour survives the training rollouts' noise."""

    physics = env.cpu_physics
    m = physics.model
    n, nu = qpos.shape[0], m.nu
    sim_dt = float(m.opt.timestep)
    b = physics.evaluation_batch(n)
    b.qpos[:], b.qvel[:], b.qacc_warmstart[:], b.time[:] = qpos, qvel, 0.0, 0.0
    hold = qpos[:, 7:7 + nu]                         # hold the start pose until the first action,
    physics.write_targets(b, hold, hold)             # the runtime supervisor's last target too
    b.forward()

    phase0 = jnp.asarray(obsdef.initial_gait_phase(np), jnp.float32)

    def act_one(params, data, last_action):
        obs_state = env.observation_state(data, jnp.zeros(3), last_action, phase0)
        r = env.body_readings(data)
        action, q_des = policy.act(params, obs_state, r)
        kneeling = events.kneeling_posture(data.qpos[7:], jnp).astype(jnp.float32)
        return action, q_des, jnp.stack([r["trunk_height"], r["up_z"], r["waist_height"], kneeling])

    act = jax.jit(jax.vmap(act_one, in_axes=(None, 0, 0)))
    scratch = mujoco.MjData(m)
    world_geom = m.geom_bodyid == 0
    force6 = np.zeros(6)

    def host_data():
        return HostData(*(jnp.asarray(a) for a in physics.read(b, (n,))))

    noise = np.random.default_rng(noise_seed)
    readings = np.zeros((n, num_ticks + 1, 4), np.float32)
    series = {k: np.zeros((n, num_ticks), np.float32)
              for k in ("energy_J", "max_energy_J", "max_torque_Nm", "torque_integral", "max_qacc", "qacc_integral",
                        "contact_force_N", "contact_force_z_N")}
    kept_qpos = np.zeros((n, num_ticks + 1, m.nq), np.float32) if keep_qpos else None
    # (23,); (2, 23) for a composite; ((3, 23), stage) for a chain
    last_action = jax.tree.map(lambda x: jnp.broadcast_to(jnp.asarray(x), (n,) + np.shape(x)),
                               policy.initial_last_action())
    for tick in range(num_ticks):
        last_action, q_des, r = act(policy.params, host_data(), last_action)
        readings[:, tick] = np.asarray(r)
        if keep_qpos:
            kept_qpos[:, tick] = b.qpos
        q_des = np.asarray(q_des)
        if target_noise_rad > 0:
            q_des = q_des + noise.normal(0.0, target_noise_rad, q_des.shape)
        physics.write_targets(b, q_des)
        for _ in range(env.n_substeps):
            dq0 = b.qvel[:, 6:].copy()
            b.step(nstep=1)
            tau, qacc = np.abs(b.actuator_force), np.abs(b.qacc[:, 6:])
            energy = np.sum(tau * np.abs(dq0), axis=1) * sim_dt
            series["energy_J"][:, tick] += energy
            series["max_energy_J"][:, tick] = np.maximum(series["max_energy_J"][:, tick], energy)
            series["max_torque_Nm"][:, tick] = np.maximum(series["max_torque_Nm"][:, tick], tau.max(axis=1))
            series["torque_integral"][:, tick] += tau.sum(axis=1) * sim_dt
            series["max_qacc"][:, tick] = np.maximum(series["max_qacc"][:, tick], qacc.max(axis=1))
            series["qacc_integral"][:, tick] += qacc.sum(axis=1) * sim_dt
        for i in range(n):
            b.get_data(i, scratch)
            normal = vertical = 0.0
            for j in range(scratch.ncon):
                con = scratch.contact[j]
                if con.dist < 0.0 and con.efc_address >= 0 and world_geom[con.geom].any():
                    mujoco.mj_contactForce(m, scratch, j, force6)
                    normal += abs(force6[0])
                    vertical += abs(force6[:3] @ con.frame.reshape(3, 3)[:, 2])   # contact frame rows → world z
            series["contact_force_N"][i, tick] = normal
            series["contact_force_z_N"][i, tick] = vertical
    readings[:, num_ticks] = np.asarray(act(policy.params, host_data(), last_action)[2])
    if keep_qpos:
        kept_qpos[:, num_ticks] = b.qpos
        series["qpos"] = kept_qpos
    return {"readings": readings, **series}

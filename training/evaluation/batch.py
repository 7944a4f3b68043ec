"""Batched getup evaluation of policy ARTIFACTS (the files the runtime runs), seed's chapter 6.

    python -m training evaluate --policy policies/getup.safetensors \
        --baseline policies/getup_baseline/getup_baseline.safetensors \
        --task getup --seeds 32 --seconds 10 --out out/eval_getup [--backend cpu|mjx]

N seeded fallen starts (the env's fallen_starts: the settled fall after the runtime's PREPARE ramp, as
`make eval-getup` hands them to the policy) are rolled out in parallel with the getup env's model
and motor law, on either physics backend (default as `train`): MJX (jax.vmap over envs, lax.scan over
control ticks, make_rollout below) or MuJoCo C (training/evaluation/cpu.py, the same series). The policy side is the
artifact run through common/observation.py with xp=jax.numpy (training/evaluation/artifact_policy.py): the
observation is built from the physics state exactly as the runtime builds it (no noise, command 0, gait clock
frozen at its initial phase because ‖command‖ < phase_freeze_command_norm), normalised, fed through the MLP, mapped to
targets. A policy may also be the runtime's composite of two artifacts, `--policy GETUP,UPRIGHT` (CompositePolicy:
the getup member below waist 0.5 m, the upright one above), the seed's chapter-6 baseline.

Per env and control tick the host gets trunk height, up_z, waist height, and per-substep aggregates:
energy Σ|τ·q̇|·dt_sim [J], the largest of one substep's Σ|τ·q̇|·dt_sim [J], max |τ| [N·m], Σ|τ|·dt_sim [N·m·s],
max |q̈| [rad/s²], Σ|q̈|·dt_sim [rad/s]; after the tick, the total normal force [N] and the world-z force [N]
of the robot's contacts with the world (Table 4.3's definitions and names: common/effort.py). Falls / attempts /
success / time to stand come from common/events.py, the definitions the HIL evaluation uses too. Output:
report.md (table beside the seed's numbers), per_env.csv, plots.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from mujoco import mjx
from mujoco.mjx._src import support

from common import events
from common import model as t1model
from common import observation as obsdef
from common.effort import EFFORT_KEYS as TABLE_4_3_KEYS
from common.effort import EFFORT_METRICS, effort_metrics
from common.events import getup_events, reached_kneel
from messages.contract import WAIST_SWITCH_HEIGHT_M
from training import envs
from training.core import checkpoints, plots
from training.core.backend import default_backend
from training.envs.starts import landing_bank
from training.evaluation import kneel_rows, table_4_3
from training.evaluation.artifact_policy import ArtifactPolicy, ChainPolicy, CompositePolicy, load_policy
from training.evaluation.cpu import cpu_rollout


def make_rollout(env, policy: ArtifactPolicy | CompositePolicy | ChainPolicy, num_ticks: int):
    """jitted (params, qpos [N, nq], qvel [N, nv]) → dict of (N, T + 1) / (N, T) series."""

    m = env.mjx_model
    sim_dt = float(env.mj_model.opt.timestep)
    phase0 = jnp.asarray(obsdef.initial_gait_phase(np), jnp.float32)

    world_geom = jnp.asarray(env.mj_model.geom_bodyid == 0)

    def contact_totals(d):
        """(Σ normal force, Σ |world-z force|) [N] over the robot's penetrating contacts with the world;
        contact slots and their dims are static in MJX."""
        con = d._impl.contact
        normal, vertical = jnp.float32(0.0), jnp.float32(0.0)
        for dim in np.unique(np.asarray(con.dim)):
            force, idx = support.contact_force_dim(m, d, int(dim))
            active = (con.dist[idx] < 0.0) & jnp.any(world_geom[con.geom[idx]], axis=1)
            fz = jnp.sum(force[:, :3] * con.frame[idx][:, :, 2], axis=1)   # contact frame rows → world z
            normal += jnp.sum(jnp.where(active, jnp.abs(force[:, 0]), 0.0))
            vertical += jnp.sum(jnp.where(active, jnp.abs(fz), 0.0))
        return normal, vertical

    def readings(d):
        r = env.body_readings(d)
        kneeling = events.kneeling_posture(d.qpos[7:], jnp).astype(jnp.float32)
        return jnp.stack([r["trunk_height"], r["up_z"], r["waist_height"], kneeling])

    def control_tick(carry, params):
        d, last_action, target = carry
        obs_state = env.observation_state(d, jnp.zeros(3), last_action, phase0)
        action, q_des = policy.act(params, obs_state, env.body_readings(d))

        def substep(c, _):
            d, agg, target = c
            tau, target = env.substep_torque(q_des, target, d.qpos[7:], d.qvel[6:])
            power = jnp.sum(jnp.abs(tau * d.qvel[6:]))  # [W], joint velocity at the start of the substep
            d = mjx.step(m, d.replace(ctrl=tau))
            qacc = jnp.abs(d.qacc[6:])
            # sums: energy, Σ|q̈|·dt, Σ|τ|·dt; maxima: |τ|, |q̈|, one substep's energy
            sums = agg[:3] + jnp.stack([power, jnp.sum(qacc), jnp.sum(jnp.abs(tau))]) * sim_dt
            maxima = jnp.maximum(agg[3:], jnp.stack([jnp.max(jnp.abs(tau)), jnp.max(qacc), power * sim_dt]))
            return (d, jnp.concatenate([sums, maxima]), target), None

        (d, agg, target), _ = jax.lax.scan(substep, (d, jnp.zeros(6), target), (), env.n_substeps)
        normal, vertical = contact_totals(d)
        out = {"readings": readings(d), "energy_J": agg[0], "qacc_integral": agg[1], "torque_integral": agg[2],
               "max_torque_Nm": agg[3], "max_qacc": agg[4], "max_energy_J": agg[5],
               "contact_force_N": normal, "contact_force_z_N": vertical}
        return (d, action, target), out

    def rollout_one(params, qpos, qvel):
        d0 = env.make_data(qpos, qvel)
        tick = lambda carry, _: control_tick(carry, params)  # noqa: E731
        first = jax.tree.map(jnp.asarray, policy.initial_last_action())
        _, series = jax.lax.scan(tick, (d0, first, env.start_target(qpos)),
                                 (), num_ticks)
        series["readings"] = jnp.concatenate([readings(d0)[None], series["readings"]], axis=0)
        return series

    return jax.jit(jax.vmap(rollout_one, in_axes=(None, 0, 0)))


def run_policy(env, policy: ArtifactPolicy | CompositePolicy | ChainPolicy, qpos, qvel, seconds: float,
               target_noise_rad: float = 0.0, noise_seed: int = 0) -> dict:
    """Roll out and reduce to per-env metrics (numpy) plus the height series for plots (target noise:
    evaluate_cpu.cpu_rollout's, CPU backend only)."""
    ctrl_dt = float(policy.manifest["control_dt"])
    ticks = int(round(seconds / ctrl_dt))
    if ticks < 1:
        raise ValueError(f"--seconds {seconds}: shorter than one control tick ({ctrl_dt} s)")
    if not target_noise_rad >= 0:
        raise ValueError(f"--target-noise {target_noise_rad}: a standard deviation [rad], >= 0")
    if target_noise_rad > 0 and env.backend != "cpu":
        raise ValueError("--target-noise: the CPU backend's rollouts only (--backend cpu)")
    if env.backend == "cpu":
        series = cpu_rollout(env, policy, np.asarray(qpos), np.asarray(qvel), ticks,
                             target_noise_rad=target_noise_rad, noise_seed=noise_seed)
    else:
        series = jax.tree.map(np.asarray, make_rollout(env, policy, ticks)(policy.params, qpos, qvel))
    readings = series["readings"]                      # (N, T + 1, 4): trunk, up_z, waist, kneeling
    t = np.arange(ticks + 1) * ctrl_dt
    forward_z = t1model.trunk_forward_z(np.asarray(qpos))
    rows = [{**episode_row(t, readings[i], {k: v[i] for k, v in series.items() if k != "readings"}),
             "start_forward_z": float(forward_z[i])} for i in range(readings.shape[0])]
    return {"rows": rows, "t": t, "trunk_height": readings[:, :, 0], "waist_height": readings[:, :, 2],
            "up_z": readings[:, :, 1]}


def episode_row(t, readings, series) -> dict:
    """One episode's metrics from its readings (T + 1, 3 or 4: trunk height, up_z, waist height[, kneeling
    posture]) at times t [s] and its per-tick effort series (T,). energy_to_stand_J counts the ticks before the
    first stand-up only (nan if it never stood): the energy of getting up, which the whole episode's energy_J
    mixes with the standing that follows it under the upright policy. The kneel's figures: kneel_rows.kneel_row."""
    ev = getup_events(t, readings[:, 0], readings[:, 1], waist_height=readings[:, 2],
                      switch_height_m=WAIST_SWITCH_HEIGHT_M)
    stood = not math.isnan(ev.time_to_stand_s)
    stand_tick = int(np.searchsorted(t, t[0] + ev.time_to_stand_s - 1e-9)) if stood else 0
    ctrl_dt = float(t[1] - t[0])
    # Table 4.3 (common/effort.py) from the per-tick sums of the substeps: already integrals over the tick
    effort = effort_metrics(series["energy_J"], series["max_energy_J"], series["max_torque_Nm"],
                            series["torque_integral"], series["max_qacc"], series["qacc_integral"],
                            series["contact_force_N"])
    return {
        "success": ev.success, "time_to_stand_s": ev.time_to_stand_s, "attempts": ev.attempts,
        "falls": ev.falls, "down_phases": ev.falls + int(ev.started_down),
        "failed_after_switch": ev.failed_after_switch,
        "reached_kneel": float(reached_kneel(readings[:, 0], readings[:, 1])),
        "gate_while_standing": events.gate_while_standing(readings[:, 0], readings[:, 1]),
        **kneel_rows.kneel_row(t, readings, ev, series["energy_J"]),
        "peak_trunk_m": float(readings[:, 0].max()),
        "energy_J": effort["energy_J"],
        "energy_to_stand_J": float(series["energy_J"][:stand_tick].sum()) if stood else math.nan,
        **{key: effort[key] for key in TABLE_4_3_KEYS[1:]},
        "z_contact_impulse_Ns": float(series["contact_force_z_N"].sum() * ctrl_dt)}


# Table 4.3's (common/effort.py) with the getup's own energy and the vertical impulse
EFFORT_KEYS = (TABLE_4_3_KEYS[0], "energy_to_stand_J", *TABLE_4_3_KEYS[1:], "z_contact_impulse_Ns")


def _lies(side: str):
    """Rows whose start lay that way (rows from episode_row alone carry no start state: on neither side)."""
    return lambda r: events.lying_side(r.get("start_forward_z", 0.0)) == side


def summarize(rows: list[dict]) -> dict:
    def mean(key, where=None):
        vals = [r[key] for r in rows if (where is None or where(r)) and not math.isnan(r[key])]
        return float(np.mean(vals)) if vals else math.nan

    def median(key):
        vals = [r[key] for r in rows if not math.isnan(r[key])]
        return float(np.median(vals)) if vals else math.nan
    # the down phases: a start lying down (every fallen start) and each fall during the episode (a bank's
    # mid-fall start is down only once it lands: that landing is one of its falls)
    falls_total = max(1, sum(r["down_phases"] for r in rows))
    return {"episodes": len(rows), "success_rate": float(np.mean([r["success"] for r in rows])),
            "attempts_per_fall": sum(r["attempts"] for r in rows) / falls_total,
            "attempts_per_episode": float(np.mean([r["attempts"] for r in rows])),
            "max_attempts": max(r["attempts"] for r in rows),
            "failed_after_switch_per_episode": float(np.mean([r["failed_after_switch"] for r in rows])),
            "never_rose": float(np.mean([r["attempts"] == 0 and not r["success"] for r in rows])),
            "time_to_stand_s": mean("time_to_stand_s"), "median_time_to_stand_s": median("time_to_stand_s"),
            "through_kneel_gate": mean("through_kneel_gate"), "through_kneel_band": mean("through_kneel_band"),
            "standing_power_W": median("standing_power_W"),
            "reached_kneel": mean("reached_kneel"),
            "reached_kneel_face_down": mean("reached_kneel", _lies("face_down")),
            "reached_kneel_face_up": mean("reached_kneel", _lies("on_back")),
            "kneeled": mean("kneeled"),
            "kneeled_face_down": mean("kneeled", _lies("face_down")),
            "kneeled_face_up": mean("kneeled", _lies("on_back")),
            "kneel_held": mean("kneel_held"), "gate_while_standing": mean("gate_while_standing"),
            **{k: mean(k) for k in EFFORT_KEYS}}


START_KINDS = ("fallen", "knockdown", "wall", "push")   # fallen: the loop's fallen starts; knockdown: mid-fall after
# a push; wall: mid-fall after walking into the low-wall course (the getup env then has the course); push: mid-fall
# in the loop's push test (starts/push.py: its torso shoves, forward and backward 2 : 1)
JOYSTICK_STARTS = ("knockdown", "wall", "push")   # the banks a joystick expert makes
ROWS = (("success rate", "success_rate", "{:.2f}"), ("attempts per fall", "attempts_per_fall", "{:.2f}"),
        ("attempts per episode (the loop's push test counts per trial)", "attempts_per_episode", "{:.2f}"),
        ("most attempts in one episode", "max_attempts", "{:.0f}"),
        ("failed attempts per episode after the waist passed the composite's switch height",
         "failed_after_switch_per_episode", "{:.2f}"),
        ("lay without a rise to the end (share)", "never_rose", "{:.3f}"),
        ("time to stand [s]", "time_to_stand_s", "{:.2f}"),
        ("median time to stand [s]", "median_time_to_stand_s", "{:.2f}"),
        ("through §4.8's kneel gate before standing (in the kneeling posture; share of those that stood)",
         "through_kneel_gate", "{:.2f}"),
        ("through the kneel band before standing (in the kneeling posture; share of those that stood)",
         "through_kneel_band", "{:.2f}"),
        (f"power while standing, median over episodes standing ≥ {kneel_rows.STANDING_POWER_MIN_S:g} s [W]",
         "standing_power_W", "{:.0f}"),
        ("reached the kneel: the gate met while not standing (share of episodes; stage 1's aim)", "reached_kneel",
         "{:.2f}"),
        ("… from starts lying face down (trunk's forward axis pointing down)", "reached_kneel_face_down", "{:.2f}"),
        ("… from starts lying on the back (trunk's forward axis pointing up)", "reached_kneel_face_up", "{:.2f}"),
        ("the gate met in the kneeling posture (both knees down; share of episodes)", "kneeled", "{:.3f}"),
        ("… from starts lying face down", "kneeled_face_down", "{:.3f}"),
        ("… from starts lying on the back", "kneeled_face_up", "{:.3f}"),
        (f"… held ≥ {events.KNEEL_HOLD_S:g} s (share of those that met it)", "kneel_held", "{:.2f}"),
        ("§4.8's gate while standing (share of standing ticks; the full task's standing rewards)",
         "gate_while_standing", "{:.3f}"),
        # Table 4.3's rows as common/effort.py labels them (a table cell escapes |), the getup's own energy after
        # the episode's
        *((label.replace("|", "\\|"), key, fmt) for key, label, fmt in EFFORT_METRICS[:1]),
        ("energy until the first stand-up [J] (episodes that stood)", "energy_to_stand_J", "{:.1f}"),
        *((label.replace("|", "\\|"), key, fmt) for key, label, fmt in EFFORT_METRICS[1:]),
        ("z contact impulse Σ\\|F_z\\|·dt [N·s]", "z_contact_impulse_Ns", "{:.0f}"))


def _fmt(fmt, value):
    return "n/a" if value is None or (isinstance(value, float) and math.isnan(value)) else fmt.format(value)


def markdown_report(results: dict, meta: dict) -> str:
    names = list(results)
    starts = meta.get("starts", "fallen")
    from_bank = starts != "fallen"   # a bank of landings: the seed's figures do not apply
    if starts == "knockdown":
        title = (f"{meta['episodes']} knockdown landings (of {meta['seeds']} pushed standing starts, bank seed "
                 f"{meta['first_seed']}, knocked over by `{meta['start_joystick']}`)")
    elif starts == "push":
        title = (f"{meta['episodes']} landings in the loop's push test (of {meta['seeds']} standing starts shoved "
                 f"on the torso, bank seed {meta['first_seed']}, `{meta['start_joystick']}` standing)")
    elif starts == "wall":
        title = (f"{meta['episodes']} landings at a low wall (of {meta['seeds']} approaches, bank seed "
                 f"{meta['first_seed']}, walked into it by `{meta['start_joystick']}`)")
    else:
        title = f"{meta['seeds']} seeded fallen starts from seed {meta['first_seed']}"
    noise = f", joint targets + N(0, {meta['target_noise_rad']:g} rad)" if meta.get("target_noise_rad") else ""
    lines = [f"# Getup evaluation ({title}, {meta['seconds']} s each, {meta.get('backend', 'mjx')} physics{noise})",
             ""]
    for role, res in results.items():
        lines.append(f"- {role}: {res['policy'].describe()}")
    lines += ["", "Means over episodes (time to stand and energy until the first stand-up: over episodes that "
              "stood up)." + ("" if from_bank else " Seed = the seed thesis's reported figure where one exists."),
              ""]
    seed_names = [] if from_bank else names   # the seed's figures are from fallen starts only
    header = ["metric"] + [f"{n}" for n in names] + [f"seed: {n}" for n in seed_names]
    lines += ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for label, key, fmt in ROWS:
        cells = [_fmt(fmt, results[n]["summary"][key]) for n in names]
        cells += [_fmt("{:.1f}", table_4_3.SEED_REPORTED.get(key, {}).get(n)) for n in seed_names]
        lines.append("| " + " | ".join([label] + cells) + " |")
    if {"policy", "baseline"} <= set(results) and not from_bank:
        lines += ["", "Direction against the seed's Table 4.3 (the seed compares its keyframe expert with its "
                  "baseline getup: the comparison is the seed's where `policy` is a keyframe getup; "
                  "`table_4_3.png`; definitions in training/evaluation/table_4_3.py):", ""]
        lines += table_4_3.direction_rows({n: r["summary"] for n, r in results.items()})
    if {"policy", "baseline"} <= set(results):
        ratio, both = paired_energy_to_stand(results["policy"]["run"]["rows"], results["baseline"]["run"]["rows"])
        lines += ["", f"Energy until the first stand-up, paired by seed over the {both} seeds where both stood: "
                  f"policy / baseline = {_fmt('{:.2f}', ratio)} (the getup's own energy: the whole-episode "
                  "energy above also counts the standing after it)."]
    if not from_bank:
        lines += ["", *kneel_rows.side_table(results, summarize, _fmt)]
    lines += ["", f"Command: `{meta['command']}`", ""]
    return "\n".join(lines)


def paired_energy_to_stand(policy_rows: list[dict], baseline_rows: list[dict]) -> tuple[float, int]:
    """Σ energy_to_stand_J of the policy / of the baseline over the seeds where both stood up, and how many."""
    pairs = [(p["energy_to_stand_J"], b["energy_to_stand_J"]) for p, b in zip(policy_rows, baseline_rows, strict=True)
             if not (math.isnan(p["energy_to_stand_J"]) or math.isnan(b["energy_to_stand_J"]))]
    if not pairs:
        return math.nan, 0
    policy_j, baseline_j = np.sum(pairs, axis=0)
    return float(policy_j / baseline_j), len(pairs)


def plot_heights(results: dict, png: Path) -> None:
    plt = plots.pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for (role, res), color in zip(results.items(), ("tab:blue", "tab:orange")):
        run = res["run"]
        for ax, key, label in zip(axes, ("trunk_height", "waist_height", "up_z"),
                                  ("trunk height [m]", "waist height [m]", "trunk up z")):
            ax.plot(run["t"], run[key].T, color=color, alpha=0.15, linewidth=0.8)
            ax.plot(run["t"], run[key].mean(axis=0), color=color, linewidth=2, label=role)
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
    axes[0].legend()
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(png, dpi=100)
    plt.close(fig)


def kneel_figures(artifact, out, seeds: int, seconds: float, command: str, seen_seeds=frozenset()) -> dict:
    """Stage 1's figures of an artifact on the batch from fallen seeds 0 … seeds − 1 (its report in `out`): the
    share that reached the kneel, in all, face down and on the back, the share that met the gate in the kneeling
    posture (also from the seeds not in `seen_seeds`, the starts its training never began from) and of those the
    share that held it KNEEL_HOLD_S, and the median of the episodes' highest trunk height [m]."""
    evaluate(artifact, out, seeds=seeds, seconds=seconds, backend="cpu", command=command)
    with (Path(out) / "per_env.csv").open() as f:
        rows = [r for r in csv.DictReader(f) if r["role"] == "policy"]
    reached = np.array([float(r["reached_kneel"]) for r in rows])
    side = np.array([events.lying_side(float(r["start_forward_z"])) for r in rows])
    unseen = np.array([int(r["seed"]) not in seen_seeds for r in rows])
    kneeled = np.array([float(r["kneeled"]) for r in rows])
    held = np.array([float(r["kneel_held"]) for r in rows])[kneeled > 0]

    def share(x, mask=None):
        x = x if mask is None else x[mask]
        return round(float(x.mean()), 3) if x.size else None
    return {"reached_kneel": share(reached), "face_down": share(reached, side == "face_down"),
            "on_back": share(reached, side == "on_back"), "kneeled": share(kneeled),
            "kneeled_face_down": share(kneeled, side == "face_down"),
            "kneeled_on_back": share(kneeled, side == "on_back"), "kneeled_unseen": share(kneeled, unseen),
            "unseen_seeds": int(unseen.sum()),
            "kneel_held": share(held),
            "median_peak_trunk_m": round(float(np.median([float(r["peak_trunk_m"]) for r in rows])), 3)}


def evaluate(policy_path, out, baseline=None, task: str = "getup", seeds: int = 32, seconds: float = 10.0,
             first_seed: int = 0, command: str = "", backend: str | None = None, starts: str = "fallen",
             start_joystick: str | None = None, target_noise_rad: float = 0.0,
             handover_up_error: float | None = None) -> Path:
    """Run the evaluation; returns the path of report.md. starts="knockdown": instead of fallen starts, the
    states where `start_joystick`, knocked over from `seeds` standing starts (bank seed `first_seed`),
    hands over to the getup policy mid-fall (training/envs/starts/); the ones it caught are left out.
    starts="wall": the same after `start_joystick` walked into the low-wall course from `seeds` approaches
    (the getup env then has the course in its world); starts="push": after the loop's push test shoved it.
    handover_up_error: a chain policy's rise → stand hand-over (load_policy)."""
    checkpoints.jax_setup()
    if task != "getup":
        raise ValueError(f"--task {task!r}: only the getup evaluation exists so far")
    if starts not in START_KINDS:
        raise ValueError(f"starts {starts!r}: one of {START_KINDS}")
    if (starts in JOYSTICK_STARTS) != (start_joystick is not None):
        raise ValueError("a start joystick policy goes with knockdown, wall or push starts, and only with them")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    env = envs.make(task, config_overrides={"backend": backend or default_backend(),
                                            "wall_course.enable": starts == "wall"})
    if starts == "fallen":
        qpos, qvel = env.fallen_starts(seeds, first_seed)   # the loop's: after the runtime's PREPARE
    else:
        qpos, qvel = landing_bank(starts)(envs.make, env, str(start_joystick), seeds, first_seed)
    policies = {role: load_policy(path, handover_up_error if role == "policy" else None)
                for role, path in (("policy", policy_path), ("baseline", baseline))
                if path is not None}   # both checked before either runs
    for policy in policies.values():
        policy.check_env(env)
    results = {}
    for role, policy in policies.items():
        print(f"{role}: {policy.path} (trained: {policy.trained})")
        run = run_policy(env, policy, qpos, qvel, seconds, target_noise_rad, first_seed)
        results[role] = {"policy": policy, "run": run, "summary": summarize(run["rows"])}
    meta = {"seeds": seeds, "first_seed": first_seed, "seconds": seconds, "command": command or "evaluate()",
            "backend": env.backend, "starts": starts, "episodes": len(qpos), "start_joystick": start_joystick,
            "target_noise_rad": target_noise_rad}
    report = out / "report.md"
    report.write_text(markdown_report(results, meta))
    with (out / "per_env.csv").open("w", newline="") as f:
        fields = ["role", "seed", "trained"] + list(results["policy"]["run"]["rows"][0])
        writer = csv.DictWriter(f, fieldnames=fields)
        writer.writeheader()
        for role, res in results.items():
            for i, row in enumerate(res["run"]["rows"]):
                seed = i if starts in JOYSTICK_STARTS else first_seed + i   # knockdown / wall / push: the bank's row
                writer.writerow({"role": role, "seed": seed, "trained": res["policy"].trained, **row})
    plot_heights(results, out / "heights.png")
    if baseline is not None:
        table_4_3.plot_ratios({n: r["summary"] for n, r in results.items()}, out / "table_4_3.png")
    return report

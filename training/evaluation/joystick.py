"""Batched evaluation of a joystick ARTIFACT: fall rate and command tracking against the joystick expert's targets.

    python -m training evaluate --task joystick --policy policies/joystick/joystick.safetensors --seeds 256 \
        --seconds 20 --out out/eval_joystick [--backend cpu|mjx]

The episodes are the joystick env's own (training/envs/joystick.py: randomised start pose and heading,
commands drawn from the training ranges, zero with p 0.1, resampled every command_resample_steps) on flat
ground, with the nominal model (no domain randomisation), no pushes and no observation noise: the policy
is judged on tracking, not on robustness. Either physics backend steps them (default as `train`). Actions
come from the ARTIFACT (common/observation.py's MLP with xp=jax.numpy on the env's clean actor observation,
deterministic tanh(mean)), so this also checks the export.

Per episode: fell (common/events.py's fall: trunk below the fallen height), and while it has not
fallen, the tracking errors in the trunk frame: linear ‖(vx, vy)_cmd − (vx, vy)‖ and yaw-rate |ω_cmd − ω_z|
(the quantities the tracking rewards use). RMS over every tick of every episode ("all"), and over ticks at
least SETTLE_S after the last command change ("settled"), since a step in the command cannot be tracked
instantly.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from common.events import getup_events
from training import envs
from training.core import checkpoints
from training.core.backend import default_backend
from training.evaluation.artifact_policy import ArtifactPolicy, policy_action

SETTLE_S = 1.0  # [s] after a command change before "settled" tracking is counted
STEP_RESPONSE_S = (0.0, 0.2, 0.4, 0.6, 1.0, 2.0)   # times after a mid-episode command change [s]
YAW_BINS_RADPS = (0.0, 0.25, 0.5, 0.75, 1.0)   # |commanded yaw rate| bins of the yaw breakdown [rad/s]
TARGETS = {"fall_rate": 0.05, "rms_lin_vel_mps": 0.15, "rms_yaw_rate_radps": 0.2}   # policies/joystick/CARD.md


def eval_env(backend: str = "mjx"):
    """The joystick env as evaluated: no noise, no pushes, flat ground (its only terrain)."""
    cfg = envs.default_config("joystick")
    cfg.noise.level = 0.0
    cfg.push.enable = False
    cfg.backend = backend
    return envs.make("joystick", config=cfg)


def make_rollout(env, policy: ArtifactPolicy, num_ticks: int):
    """jitted (params, rngs [N, 2]) → per-tick series (N, T) of the readings the metrics need."""

    def tick(state, params):
        action = policy_action(policy.manifest, params, _clean_obs_state(env, state))
        cmd = state.info["command"]     # the command this tick's action was chosen for
        state = env.step(state, action)
        linvel, gyro = env.sensor(state.data, "local_linvel"), env.sensor(state.data, "gyro")
        out = {"cmd": cmd, "vel": jnp.stack([linvel[0], linvel[1], gyro[2]]),
               "trunk": state.info["trunk_height"], "up_z": state.info["up_z"]}
        return state, out

    def rollout_one(params, rng):
        step = lambda s, _: tick(s, params)  # noqa: E731
        return jax.lax.scan(step, env.reset(rng), (), num_ticks)[1]

    return jax.jit(jax.vmap(rollout_one, in_axes=(None, 0)))


def _clean_obs_state(env, state):
    return env.observation_state(state.data, state.info["command"], state.info["last_act"], state.info["phase"])


def episode_rows(series: dict, ctrl_dt: float) -> list[dict]:
    """Per-episode fall flag and squared-error sums (numpy; split out for tests on synthetic series)."""
    cmd, vel = np.asarray(series["cmd"]), np.asarray(series["vel"])      # (N, T, 3)
    n, t_len = cmd.shape[:2]
    t = (np.arange(t_len) + 1) * ctrl_dt
    settle = int(round(SETTLE_S / ctrl_dt))
    rows = []
    for i in range(n):
        ev = getup_events(t, np.asarray(series["trunk"][i]), np.asarray(series["up_z"][i]))
        upto = int(np.searchsorted(t, ev.fall_times_s[0])) if ev.falls else t_len
        changed = np.flatnonzero(np.any(np.diff(cmd[i], axis=0) != 0.0, axis=1)) + 1
        last_change = np.zeros(t_len, int)
        last_change[changed] = changed
        settled = np.arange(t_len) - np.maximum.accumulate(last_change) >= settle
        err = cmd[i] - vel[i]
        lin2, yaw2 = np.sum(err[:, :2] ** 2, axis=1)[:upto], err[:upto, 2] ** 2
        rows.append({"fell": bool(ev.falls), "ticks": upto, "lin2_sum": float(lin2.sum()),
                     "yaw2_sum": float(yaw2.sum()), "settled_ticks": int(settled[:upto].sum()),
                     "lin2_settled_sum": float(lin2[settled[:upto]].sum()),
                     "yaw2_settled_sum": float(yaw2[settled[:upto]].sum())})
    return rows


def yaw_by_command(series: dict, rows: list[dict]) -> list[dict]:
    """Yaw tracking per |commanded yaw rate| bin, over the ticks before each episode's fall: RMS error
    [rad/s], gain Σ ω_z·sign(ω_cmd) / Σ |ω_cmd| (1: turns as fast as told, 0: does not turn) and signed
    bias mean(ω_z − ω_cmd) [rad/s]. Commands are drawn symmetric in yaw, so a bias is a steady veer to one
    side: what keeps a policy that tracks yaw "on average" from walking a straight course."""
    cmd = np.concatenate([np.asarray(series["cmd"])[i, :r["ticks"], 2] for i, r in enumerate(rows)])
    yaw = np.concatenate([np.asarray(series["vel"])[i, :r["ticks"], 2] for i, r in enumerate(rows)])
    out = []
    for lo, hi in zip(YAW_BINS_RADPS[:-1], YAW_BINS_RADPS[1:]):
        last = hi == YAW_BINS_RADPS[-1]
        sel = (np.abs(cmd) >= lo) & ((np.abs(cmd) <= hi) if last else (np.abs(cmd) < hi))
        c, w = cmd[sel], yaw[sel]
        out.append({"lo": lo, "hi": hi, "ticks": int(sel.sum()),
                    "rms_radps": float(np.sqrt(np.mean((c - w) ** 2))) if sel.any() else math.nan,
                    "bias_radps": float(np.mean(w - c)) if sel.any() else math.nan,
                    "gain": float(np.sum(w * np.sign(c)) / np.sum(np.abs(c))) if np.any(c) else math.nan})
    return out


def step_response(series: dict, rows: list[dict], ctrl_dt: float) -> dict:
    """How fast the linear velocity follows a mid-episode command change: the mean linear error [m/s] at each
    STEP_RESPONSE_S after the change, over the changes still standing and not yet changed again by then,
    and the mean size of the commanded step ‖Δ(vx, vy)‖ [m/s]."""
    cmd, vel = np.asarray(series["cmd"]), np.asarray(series["vel"])
    offsets = [int(round(t / ctrl_dt)) for t in STEP_RESPONSE_S]
    errs, steps = [[] for _ in offsets], []
    for i, row in enumerate(rows):
        err = np.linalg.norm(cmd[i, :, :2] - vel[i, :, :2], axis=1)
        changes = np.flatnonzero(np.any(np.diff(cmd[i], axis=0) != 0.0, axis=1)) + 1
        ends = np.append(changes[1:], row["ticks"])
        for c, end in zip(changes, np.minimum(ends, row["ticks"])):
            if c >= row["ticks"]:
                continue
            steps.append(float(np.linalg.norm(cmd[i, c, :2] - cmd[i, c - 1, :2])))
            for k, off in enumerate(offsets):
                if c + off < end:
                    errs[k].append(err[c + off])
    return {"changes": len(steps), "mean_step_mps": float(np.mean(steps)) if steps else math.nan,
            "mean_err_mps": [float(np.mean(e)) if e else math.nan for e in errs]}


def summarize(rows: list[dict]) -> dict:
    ticks = sum(r["ticks"] for r in rows)
    settled = sum(r["settled_ticks"] for r in rows)
    rms = lambda key, n: math.sqrt(sum(r[key] for r in rows) / n) if n else math.nan  # noqa: E731
    return {"episodes": len(rows), "fall_rate": float(np.mean([r["fell"] for r in rows])),
            "rms_lin_vel_mps": rms("lin2_sum", ticks), "rms_yaw_rate_radps": rms("yaw2_sum", ticks),
            "rms_lin_vel_settled_mps": rms("lin2_settled_sum", settled),
            "rms_yaw_rate_settled_radps": rms("yaw2_settled_sum", settled)}


def markdown_report(policy: ArtifactPolicy, summary: dict, meta: dict, yaw_bins: list[dict] = (),
                    response: dict | None = None) -> str:
    m = policy.manifest
    met = {k: summary[k] <= v for k, v in TARGETS.items()}
    lines = [f"# Joystick evaluation ({summary['episodes']} episodes of {meta['seconds']} s, "
             f"{meta['backend']} physics, flat, no pushes, no noise)", "",
             f"- policy `{policy.path}` name `{m['name']}`, trained: **{'yes' if m['trained'] else 'NO'}**, "
             f"env steps {m['provenance']['steps']}, content hash {m['content_hash'][:12]}", "",
             "| metric | value | target | met |", "|---|---|---|---|",
             f"| fall rate | {summary['fall_rate']:.3f} | ≤ {TARGETS['fall_rate']} | {met['fall_rate']} |",
             f"| RMS linear-velocity error, all ticks [m/s] | {summary['rms_lin_vel_mps']:.3f} | "
             f"≤ {TARGETS['rms_lin_vel_mps']} | {met['rms_lin_vel_mps']} |",
             f"| RMS yaw-rate error, all ticks [rad/s] | {summary['rms_yaw_rate_radps']:.3f} | "
             f"≤ {TARGETS['rms_yaw_rate_radps']} | {met['rms_yaw_rate_radps']} |",
             f"| RMS linear-velocity error, ≥ {SETTLE_S} s after a command change [m/s] | "
             f"{summary['rms_lin_vel_settled_mps']:.3f} | (information) | |",
             f"| RMS yaw-rate error, ≥ {SETTLE_S} s after a command change [rad/s] | "
             f"{summary['rms_yaw_rate_settled_radps']:.3f} | (information) | |",
             "", f"Targets met: **{'all' if all(met.values()) else 'NO'}**. Command: `{meta['command']}`", ""]
    if yaw_bins:
        lines += ["Yaw tracking by commanded yaw rate (gain: achieved / commanded, 1 = turns as told; bias: "
                  "mean ω_z − ω_cmd, a steady veer, + = to the left):", "",
                  "| \\|ω_cmd\\| [rad/s] | ticks | RMS error [rad/s] | gain | bias [rad/s] |",
                  "|---|---|---|---|---|"]
        lines += [f"| {b['lo']:.2f}–{b['hi']:.2f} | {b['ticks']} | {b['rms_radps']:.3f} | {b['gain']:.2f} | "
                  f"{b['bias_radps']:+.3f} |" for b in yaw_bins]
        lines.append("")
    if response and response["changes"]:
        lines += [f"Linear-velocity error after a command change ({response['changes']} mid-episode changes, "
                  f"mean step ‖Δ(vx, vy)‖ {response['mean_step_mps']:.2f} m/s):", "",
                  "| " + " | ".join(f"{t:.1f} s" for t in STEP_RESPONSE_S) + " |",
                  "|" + "---|" * len(STEP_RESPONSE_S),
                  "| " + " | ".join(f"{e:.2f}" for e in response["mean_err_mps"]) + " |", ""]
    return "\n".join(lines)


def evaluate(policy_path, out, episodes: int = 256, seconds: float = 20.0, first_seed: int = 0,
             command: str = "", backend: str | None = None) -> Path:
    """Run the evaluation; returns the path of report.md."""
    checkpoints.jax_setup()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    env = eval_env(backend or default_backend())
    policy = ArtifactPolicy.load(policy_path)
    policy.check_env(env)
    ticks = int(round(seconds / env.dt))
    if ticks < 1:
        raise ValueError(f"--seconds {seconds}: shorter than one control tick ({env.dt} s)")
    rngs = jax.random.split(jax.random.PRNGKey(first_seed), episodes)
    series = jax.tree.map(np.asarray, make_rollout(env, policy, ticks)(policy.params, rngs))
    rows = episode_rows(series, float(env.dt))
    summary = summarize(rows)
    report = out / "report.md"
    report.write_text(markdown_report(policy, summary, {"seconds": seconds, "command": command or "evaluate()",
                                                          "backend": env.backend}, yaw_by_command(series, rows),
                                          step_response(series, rows, float(env.dt))))
    with (out / "per_episode.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=["episode", *rows[0]])
        writer.writeheader()
        for i, row in enumerate(rows):
            writer.writerow({"episode": i, **row})
    return report

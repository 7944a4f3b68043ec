"""Report of one evaluation scenario under out/eval/<scenario>/: report.md (our numbers beside the seed's
student and baseline figures, every trial beside the seed's per-trial tables, the policies' "trained" flags
at the top and next to every table), plots.png (trunk height, waist height,
forward velocity of a representative trial, as the seed's Fig. 5.1), video.mp4, results.json."""
from __future__ import annotations

import json
from dataclasses import asdict
from datetime import datetime, timezone
from pathlib import Path

from common import events, keyframe_chain
from common.artifact import read_artifact
from common.seed_figures import SEED_FIGURES, SEED_TRIAL_TABLES, seed_cells, seed_columns
from messages import contract
from sim_hil.eval import metrics
from sim_hil.eval.plans import COMMON_ROWS, Plan
from sim_hil.eval.trial import Controller, TrialResult
from sim_hil.plots import plot_heights_and_velocity


def trained_flags(controllers: list[Controller]) -> dict[str, bool]:
    """'<label>' (and '<label> upright' for a composite) -> manifest "trained"."""
    flags = {}
    for c in controllers:
        flags[c.label if not c.upright else f"{c.label} getup"] = all(
            bool(read_artifact(p)[3]["trained"]) for p in keyframe_chain.artifact_files(c.policy))
        if c.upright:
            flags[f"{c.label} joystick"] = bool(read_artifact(c.upright)[3]["trained"])
    return flags


def trained_line(flags: dict[str, bool]) -> str:
    parts = ", ".join(f"{k}: {'trained' if v else 'UNTRAINED'}" for k, v in flags.items())
    return f"_Policies — {parts}. Numbers of an UNTRAINED policy show the plumbing, not a result._" \
        if not all(flags.values()) else f"_Policies — {parts}._"


def write_report(out: Path, plan: Plan, controllers: list[Controller], results: list[TrialResult],
                 command: str, trials: int, seconds: float, wall_s: float, video: Path | None) -> dict[str, Path]:
    out.mkdir(parents=True, exist_ok=True)
    flags = trained_flags(controllers)
    by_label = {c.label: [r for r in results if r.controller == c.label] for c in controllers}
    rows = {label: plan.rows(trials_of) for label, trials_of in by_label.items()}

    # plot: trial 0 of every controller (the representative trial: the first seed, the same for all)
    # (the teacher first, as the seed's Fig. 5.1 reads left to right: teacher, then students)
    series = {label: min(rs, key=lambda r: r.spec.seed).plot
              for label, rs in sorted(by_label.items(), key=lambda kv: kv[0] != "teacher") if rs}
    cmd_vx = results[0].spec.command_vx_mps if results else 0.0
    plot = plot_heights_and_velocity(
        series, out / "plots.png",
        f"{plan.name}: seed {min(r.spec.seed for r in results)} "
        "(" + ", ".join(f"{k} {'trained' if v else 'UNTRAINED'}" for k, v in flags.items()) + ")",
        command_vx=[(0.0, cmd_vx)] if cmd_vx else None, side_by_side=plan.side_by_side)

    lines = [f"# Evaluation `{plan.name}`: {plan.description}", "",
             trained_line(flags), ""]
    for c in controllers:
        members = (f"getup `{c.policy}` + joystick `{c.upright}` (composite, switched at waist "
                   f"{contract.WAIST_SWITCH_HEIGHT_M:g} m)" if c.upright else
                   f"`{c.policy}` (keyframe chain roll → rise → stand, switched on the sim's Trunk height)"
                   if keyframe_chain.is_chain(c.policy) else f"`{c.policy}`")
        lines.append(f"- **{c.label}**: {members}")
    lines += ["", f"Command: `{command}`  ",
              f"{trials} seeded trial(s) per policy, {seconds:g} s of sim time each, "
              f"{' + '.join(sorted({r.spec.clock for r in results}))}, "
              f"{datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC, {wall_s:.0f} s wall.", ""]
    if not all(flags.values()):
        lines += ["> **No result is claimed here**: at least one policy's manifest says `trained: false`.", ""]

    labels = list(rows)
    keys = list(dict.fromkeys(k for r in rows.values() for k in r))
    seeded = plan.name in SEED_FIGURES        # walk (the joystick expert's targets) has no seed table
    seed_heads = list(seed_columns(plan.name)) if seeded else []
    lines += ["## Results", "", trained_line(flags), ""]
    lines += _table(["metric", *labels, *seed_heads],
                    [[k, *(rows[lb].get(k, "") for lb in labels),
                      *((["—", "—"] if k in COMMON_ROWS else seed_cells(plan.name, k)) if seeded else [])]
                     for k in keys])
    lines += ["", "Values: mean ± std over trials (one value: a single trial).", ""]
    lines += _per_trial(plan, results, flags)

    th = events.EventThresholds()
    lines += ["## Definitions", "",
              f"- Events (`common/events.py`, also used by the MJX evaluator): fallen = trunk below "
              f"{th.fallen_trunk_height_m} m; standing = trunk ≥ {th.standing_trunk_threshold_m} m and up_z ≥ "
              f"{th.upright_up_z}, held {th.stand_hold_s} s; a getup attempt = a rise of {th.attempt_rise_m} m "
              "from the lowest height while down (hysteresis both ways); success = not down at the end.",
              f"- Every metric starts when the runtime first commands in POLICY (after its PREPARE ramp: "
              f"{results[0].spec.prepare_s:g} s here).",
              "- Table 4.3 metrics (`common/effort.py`, the batch's names) from the in-process physics, over the first "
              "down phase up to its stand-up; torque = motor torque from the firmware PD, dt = 2 ms.",
              f"- Slip: a foot carrying ≥ {metrics.SLIP_LOAD_N:g} N sliding ≥ {metrics.SLIP_SPEED_MPS} m/s "
              f"for ≥ {metrics.SLIP_MIN_S * 1e3:g} ms. Ran to stabilise: no fall and trunk speed ≥ "
              f"{metrics.RUN_SPEED_MPS} m/s for ≥ {metrics.RUN_MIN_S:g} s.", "",
              "## Plots and video", "", trained_line(flags), "",
              f"![trunk height, waist height, forward velocity]({plot.name})", ""]
    if video is not None and video.exists():
        lines += [f"Video of {controllers[0].label}'s first trial: [{video.name}]({video.name})", ""]
    logs = [Path(r.spec.log) for r in results if r.spec.log]
    if logs:
        lines += [f"LCM log of every trial: `{logs[0].parent.name}/` (e.g. `{logs[0].name}`): replay one with "
                  f"`make replay LOG=…` (lcm-spy) or `make replay LOG=… POLICY=…` (runtime re-run), plot it with "
                  "`make plot-log LOG=…`.", ""]
    report = out / "report.md"
    report.write_text("\n".join(lines))

    dump = {"scenario": plan.name, "trained": flags, "rows": rows, "trials": [
        {k: v for k, v in asdict(r).items() if k != "plot"} for r in results]}
    # NaN (no stand-up, DNF) becomes null: strict JSON for any reader
    plain = json.loads(json.dumps(dump, default=str), parse_constant=lambda _c: None)
    (out / "results.json").write_text(json.dumps(plain, indent=1))
    paths = {"report": report, "plot": plot, "results": out / "results.json"}
    if video is not None and video.exists():  # a failed recording is reported with its trial, not listed
        paths["video"] = video
    if logs:
        paths["logs"] = logs[0].parent
    return paths


def _table(header: list[str], body: list[list[str]]) -> list[str]:
    def cell(text: str) -> str:
        return str(text).replace("|", "\\|")        # Σ|τ·q̇| must not split a markdown cell
    return ["| " + " | ".join(map(cell, header)) + " |", "|" + "---|" * len(header),
            *("| " + " | ".join(map(cell, row)) + " |" for row in body)]


def _per_trial(plan: Plan, results: list[TrialResult], flags: dict[str, bool]) -> list[str]:
    """Every trial's own cells, then the seed's per-trial tables of this scenario (verbatim)."""
    cells = [plan.trial_cells(r) for r in results]
    keys = list(dict.fromkeys(k for c in cells for k in c))
    lines = ["## Per trial", "", trained_line(flags), ""]
    lines += _table(["policy", "seed", *keys], [[r.controller, str(r.spec.seed), *(c.get(k, "") for k in keys)]
                                                 for r, c in zip(results, cells)])
    for t in SEED_TRIAL_TABLES.get(plan.name, ()):
        lines += ["", f"The seed's {t.title}:", "", *_table(list(t.header), [list(row) for row in t.rows])]
        if t.note:
            lines += ["", t.note]
    return [*lines, ""]

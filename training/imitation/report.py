"""The DAgger campaign's report: one row per round (labels, CPU hours, the batch share that reached the kneel, in
all, face down and on the back) as report.md, and the share against the labels as curve.png."""
from __future__ import annotations

from pathlib import Path

from training.core import plots

COLUMNS = (("round", "round"), ("beta", "β"), ("policy", "rolled out (– : the learner)"),
           ("lying", "from starts lying (– : any)"), ("labels", "labels"),
           ("labels_total", "labels in total"),
           ("cpu_s_per_label", "CPU s per label"), ("cpu_hours_total", "labelling CPU h in total"),
           ("expert_kind", "expert"), ("rollouts_met_gate", "rollouts that met the gate (β mixture; best of K)"),
           ("policy_met_gate", "… by the policy alone"),
           ("fit_loss", "fit loss (share of var)"), ("reached_kneel", "reached the kneel (batch)"),
           ("face_down", "… face down"), ("on_back", "… on the back"),
           ("kneeled", "the gate in the kneeling posture (batch)"), ("kneel_held", "… held ≥ 1 s (of those)"),
           ("median_peak_trunk_m", "median peak trunk height [m]"))


def table(rows: list[dict], columns=COLUMNS) -> str:
    """A markdown table of rows, one column per (key, heading)."""
    head = "| " + " | ".join(c[1] for c in columns) + " |\n|" + "---|" * len(columns) + "\n"
    return head + "".join("| " + " | ".join(_cell(r.get(k)) for k, _ in columns) + " |\n" for r in rows)


def _cell(v) -> str:
    if isinstance(v, list):
        return ", ".join(map(_cell, v))
    return "–" if v is None else f"{v:g}" if isinstance(v, float) else str(v)


def expert_kind(row: dict) -> str:
    """A round's expert in words: the planner's takeovers, or best-of-K rises of the policy."""
    bok = (row.get("expert") or {}).get("best_of_k", {})
    return f"best of {bok['k']} (σ {bok['sigma_rad']:g} rad)" if bok.get("k") else "planner"


def write(folder: Path, state: dict) -> None:
    rows = [{**r, "expert_kind": expert_kind(r)} if r["round"] > 0 else r for r in state["rounds"]]
    cfg = state["config"]["dagger"]
    text = ("# DAgger with the planner as the expert\n\n"
            f"Rollouts per round: {cfg['starts_per_round']} fallen starts × {cfg['rollout_s']} s; the planner's "
            f"takeover {cfg['expert']['takeover_replans']} replans from each segment's start "
            f"({cfg['expert']['policy_samples']} policy + {cfg['expert']['plan_samples']} plan samples, horizon "
            f"{state['config']['planner']['horizon_s']} s), or best-of-K rises of the policy (best_of_k.py); batch "
            f"evaluation from {cfg['eval_seeds']} fallen seeds × {cfg['eval_seconds']} s "
            "(training/evaluation/batch.py, "
            f"\"reached the kneel\").\n\n" + table(rows))
    (Path(folder) / "report.md").write_text(text)
    _curve(rows, Path(folder) / "curve.png")


def _curve(rows: list[dict], png: Path) -> None:
    plt = plots.pyplot()
    fig, ax = plt.subplots(figsize=(6, 3.5))
    x = [r["labels_total"] for r in rows]
    for key, label in (("reached_kneel", "all"), ("face_down", "face down"), ("on_back", "on the back")):
        ax.plot(x, [r[key] for r in rows], "o-", label=label)
    ax.set_xlabel("labels in the data set")
    ax.set_ylabel("reached the kneel (batch share)")
    ax.set_ylim(0, 1)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(png, dpi=100)
    plt.close(fig)

"""DAgger rounds with the planner as the expert (Ross et al. 2011; PLATO's MPC teacher near the learner's states).

Round 0 fits the learner to the planner's stored demonstrations. Round k ≥ 1 rolls the current learner out from
fresh fallen starts, all at once on the C physics; at the start of every segment (takeover_replans replans) the
planner takes over a copy of each robot (expert.Teacher.takeover) and every step of it is a label; with
probability β the robot goes on from where the expert's takeover left it (the expert acted), else from where the
learner's own segment did. The labels join the data set, the learner is refitted on all of it, exported and
evaluated on the batch from `eval_seeds` fallen seeds (training/evaluation/batch.py's "reached the kneel")."""
from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import numpy as np

from common.events import LYING_SIDES
from training.core import checkpoints
from training.core.checkpoints import repo_relative
from training.envs.starts.rolled import rolled_bank
from training.evaluation.batch import kneel_figures
from training.imitation import best_of_k, config, dataset, expert, report
from training.imitation.learner import fit, load_learner, new_learner
from training.planner.demos import start_side

REPO_ROOT = Path(__file__).resolve().parents[2]
DEFAULT_DEMOS = REPO_ROOT / "training" / "campaigns" / "getup_keyframe" / "demos"   # the planner's stored rises
STATE, ARTIFACT, DATA, COLLECTED = config.STATE, config.ARTIFACT, config.DATA, config.COLLECTED
LYING_DRAWS = 4    # a round from one lying side draws its starts from this many times as many seeds (each side ~0.4)
LYING_DOUBLINGS = 3   # … doubled up to this many times where those seeds hold too few of the side
ROLLED_DRAWS = 3   # a round from a roll's hand-overs draws from this many times as many seeds (~0.6 lie on the back
                   # or side; a bank's draws repeat some)


def beta(cfg, k: int) -> float:
    return 0.0 if k == 0 else float(cfg.beta_start) * float(cfg.beta_decay) ** (k - 1)


def collect(teacher: expert.Teacher, learner, qpos: np.ndarray, qvel: np.ndarray, beta_k: float,
            rollout_s: float, rng: np.random.Generator) -> dict:
    """One round's rollouts and labels from the starts (qpos, qvel); returns the labels, how many rollouts met
    §4.8's gate in the kneeling posture, and the CPU seconds spent."""
    p = teacher.p
    cpu0 = time.process_time()
    n = len(qpos)
    main, plans, waypoint = teacher.start(qpos, qvel)
    branch = expert.Robots(p.physics, n)
    seg = int(teacher.cfg.takeover_replans) * p.replan_knots * p.spk
    steps = int(round(rollout_s / p.ctrl_dt))
    met = np.zeros(n, bool)
    obs, q = [], []
    for _ in range(0, steps, seg):
        branch.copy_from(main)
        out = teacher.takeover(branch, plans, waypoint.copy(), learner.targets, rng)
        obs.append(out["obs"])
        q.append(out["q_des"])
        for _ in range(seg):
            main.step(learner.targets(teacher.observe(main)))
            waypoint = teacher.advance_waypoints(main, waypoint)
            met |= teacher.at_gate(main)
        acted = rng.random(n) < beta_k
        main.take_rows(branch, acted)
        waypoint = np.where(acted, out["waypoint"], waypoint)
        plans = out["plans"]
    return {"obs": np.concatenate(obs), "q_des": np.concatenate(q), "met_gate": int(met.sum()),
            "cpu_s": time.process_time() - cpu0}


def manifest(env_fields: dict, labels: int, k: int, started: float) -> dict:
    """The artifact's manifest: the getup env's fields, a name and DAgger's provenance (labels as its steps)."""
    return {**env_fields, "name": "getup_kneel", "trained": True,
            "provenance": {"git_commit": checkpoints.git_commit(), "steps": int(labels), "date": checkpoints.utc_now(),
                           "command": "python -m training.imitation", "algorithm": f"dagger, planner expert, round {k}",
                           "minutes": round((time.monotonic() - started) / 60.0, 2)}}


FIT_ONLY = ("fit", "rounds", "eval_seeds", "eval_seconds")   # settings that do not shape the data
# the expert may change between rounds (DAgger aggregates any expert's labels): each round records its own
PER_ROUND = ("expert",)


def _fitted_with(config: dict) -> dict:
    """The settings a finished round's row depends on: all but how many rounds the campaign runs and the expert."""
    return {**config, "dagger": {k: v for k, v in config["dagger"].items() if k not in ("rounds", *PER_ROUND)}}


class Campaign:
    """A DAgger run's folder: data/ (round_XX.npz from round 1 on, and collected.json: the settings that made the
    data and each round's rollout figures), the newest learner as its artifact, state.json (the whole config and
    one row per finished round), report.md and curve.png. A stopped run resumes at its next round; `refit` starts
    the rows over with the current fit settings on the stored data, whose settings must match."""

    def __init__(self, folder: Path, cfg, planner_cfg, refit: bool = False):
        self.folder, self.cfg = Path(folder), cfg
        whole = cfg.to_dict()
        self.config = {"dagger": whole, "planner": planner_cfg.to_dict()}
        self.expert = whole["expert"]
        data_config = {"dagger": {k: v for k, v in whole.items() if k not in FIT_ONLY + PER_ROUND},
                       "planner": planner_cfg.to_dict()}
        self.data = self.folder / DATA
        self.data.mkdir(parents=True, exist_ok=True)
        path = self.data / COLLECTED
        self.collected = json.loads(path.read_text()) if path.exists() else {"config": data_config, "rounds": {}}
        older = self.collected["config"]["dagger"].pop("expert", None)    # a folder from before PER_ROUND
        for stats in self.collected["rounds"].values():
            stats.setdefault("expert", older)
        if self.collected["config"] != data_config:
            raise ValueError(f"{self.data}: its rounds were collected with other settings; use a new folder")
        path = self.folder / STATE
        self.state = json.loads(path.read_text()) if path.exists() and not refit else \
            {"config": self.config, "rounds": []}
        if _fitted_with(self.state["config"]) != _fitted_with(self.config):
            raise ValueError(f"{folder}: its rounds were fitted with other settings (fit, eval): --refit redoes "
                             "them with these, or use a new folder")
        self.state["config"] = self.config      # a campaign may be given more rounds

    @property
    def next_round(self) -> int:
        return len(self.state["rounds"])

    def collected_round(self, k: int) -> dict | None:
        return self.collected["rounds"].get(str(k))

    def store_round(self, k: int, got: dict, starts: int, policy: Path | None = None, lying: str = "",
                    rolled_by: Path | None = None) -> dict:
        """Save round k's labels and its figures; `policy`: the artifact rolled out, when not the learner, kept
        beside the round's data (the labels' provenance, and what a fine-tune from it starts from, on any clone);
        `lying`: the one way its starts lay, when the round was rolled out from those alone; `rolled_by`: the
        roll whose hand-overs it started from."""
        dataset.save_round(self.data, k, got["obs"], got["q_des"])
        stats = {"rollouts": starts, "rollouts_met_gate": got["met_gate"], "labels": len(got["obs"]),
                 **({"policy_met_gate": got["policy_met_gate"]} if "policy_met_gate" in got else {}),
                 "label_cpu_s": round(got["cpu_s"], 1),
                 "cpu_s_per_label": round(got["cpu_s"] / max(len(got["obs"]), 1), 4), "expert": self.expert}
        if lying:
            stats["lying"] = lying
        if rolled_by is not None:
            stats["rolled_by"] = repo_relative(rolled_by)
        if policy is not None:
            kept = self._kept_copy(Path(policy)) or dataset.policy_path(self.data, k)
            if not kept.exists():
                shutil.copy2(policy, kept)
            stats.update(policy=repo_relative(kept), policy_from=repo_relative(policy))
        self.collected["rounds"][str(k)] = stats
        (self.data / COLLECTED).write_text(json.dumps(self.collected, indent=1))
        return stats

    def _kept_copy(self, policy: Path) -> Path | None:
        """An earlier round's kept copy of the same artifact (several rounds rolled out by one policy keep it once)."""
        data = policy.read_bytes()
        return next((q for q in dataset.kept_policies(self.data)
                     if q.stat().st_size == len(data) and q.read_bytes() == data), None)

    def finish_round(self, row: dict) -> None:
        self.state["rounds"].append(row)
        (self.folder / STATE).write_text(json.dumps(self.state, indent=1))
        report.write(self.folder, self.state)


def round_starts(env, n: int, first_seed: int, lying: str = "",
                 rolled_by: Path | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(qpos, qvel) of a round's n fallen starts, seeds first_seed …; with `lying` (common/events.py's sides) the
    first n of those seeds that lie that way (from LYING_DRAWS · n seeds, twice as many where those hold fewer:
    a small round may draw few of one side); with `rolled_by` (a roll policy) the first n distinct states where
    that roll hands over to the rise from the on-back and side starts among ROLLED_DRAWS · n seeds
    (training/envs/starts/rolled.py; fewer where those hold fewer)."""
    if rolled_by is not None:
        qpos, qvel = rolled_bank(env.make_env, str(rolled_by), ROLLED_DRAWS * n, first_seed,
                                 float(env.config.fallen.prepare_s))
        return qpos[:n], qvel[:n]
    if not lying:
        return env.fallen_starts(n, first_seed)
    draws = LYING_DRAWS * n
    for _ in range(LYING_DOUBLINGS + 1):
        qpos, qvel = env.fallen_starts(draws, first_seed)
        keep = np.flatnonzero([start_side(q) == lying for q in qpos])[:n]
        if len(keep) == n:
            return qpos[keep], qvel[keep]
        draws *= 2
    raise ValueError(f"only {len(keep)} of {draws // 2} fallen starts from seed {first_seed} lie {lying}")


def run(folder: Path, demos: Path, cfg, teacher: expert.Teacher, env, rounds: int | None = None,
        max_minutes: float | None = None, eval_dir: Path | None = None, refit: bool = False,
        policy: Path | None = None, lying: str = "", rolled_by: Path | None = None, log=print) -> dict:
    """The rounds from the campaign's next on. `policy`: an artifact of the learner's network and action map (a
    PPO fine-tune of it) that the next round rolls out and its fit starts from, in place of the campaign's
    learner: DAgger on the states that policy visits; `lying`: the next round starts only from fallen starts
    lying that way (labels where that side's rises fail); `rolled_by`: the next round starts where that roll
    policy hands the on-back and side falls over to the rise (labels where the chain's rises start)."""
    camp = Campaign(folder, cfg, teacher.p.cfg, refit)
    if lying and lying not in LYING_SIDES:
        raise ValueError(f"--lying must be one of {', '.join(LYING_SIDES)}, got {lying!r}")
    if (policy is not None or lying or rolled_by is not None) and (refit or camp.next_round == 0):
        raise ValueError("--policy, --lying and --rolled-by take over a round's rollouts: not for round 0 or a "
                         "--refit")
    if lying and rolled_by is not None:
        raise ValueError("--lying and --rolled-by are two sources of a round's starts: give one")
    data = camp.data
    eval_dir = Path(eval_dir or Path("runs") / "imitation_eval")
    fields = env.manifest_fields()
    p = teacher.p
    started = time.monotonic()
    last = int(cfg.rounds) if rounds is None else min(int(rounds), int(cfg.rounds))
    obs0, _ = dataset.demonstration_pairs(demos)
    learner = new_learner(obs0, list(cfg.fit.hidden_layer_sizes), int(cfg.fit.seed), fields, p.lo, p.hi)
    if camp.next_round > 0:
        learner = load_learner(camp.folder / ARTIFACT if policy is None else policy, learner)
    first = camp.next_round
    while camp.next_round < last:
        if max_minutes is not None and time.monotonic() - started > 60.0 * max_minutes:
            log(f"imitation: --max-minutes {max_minutes:g} reached before round {camp.next_round}")
            break
        k = camp.next_round
        b = beta(cfg, k)
        row = {"round": k, "beta": b}
        t0 = time.monotonic()
        if k > 0:
            stats = camp.collected_round(k)
            if stats is None or not dataset.round_path(data, k).exists():
                n = int(cfg.starts_per_round)
                side, roll = (lying, rolled_by) if k == first else ("", None)
                qpos, qvel = (a.astype(np.float64) for a in round_starts(env, n, int(cfg.first_seed) + (k - 1) * n,
                                                                        side, roll))
                rng = np.random.default_rng([int(cfg.seed), k])
                if int(cfg.expert.best_of_k.k) > 0:
                    got = best_of_k.collect(teacher, learner.targets, qpos, qvel, cfg.expert.best_of_k,
                                            float(cfg.rollout_s), rng)
                else:
                    got = collect(teacher, learner, qpos, qvel, b, float(cfg.rollout_s), rng)
                stats = camp.store_round(k, got, len(qpos), policy if k == first else None, side, roll)
            row.update(stats)
        obs, q = dataset.aggregate(data, demos, k + 1)
        learner, loss = fit(learner, obs, learner.label_actions(q), cfg.fit, int(cfg.fit.seed) + k)
        row.update(labels_total=len(obs), fit_loss=round(loss[-1], 4))
        artifact = camp.folder / ARTIFACT
        learner.export(artifact, manifest(fields, len(obs), k, started))
        row.update(kneel_figures(artifact, eval_dir / f"round_{k:02d}", int(cfg.eval_seeds),
                                 float(cfg.eval_seconds), "python -m training.imitation"))
        spent = sum(r.get("label_cpu_s", 0.0) for r in camp.state["rounds"]) + row.get("label_cpu_s", 0.0)
        row.update(cpu_hours_total=round(spent / 3600.0, 3), minutes=round((time.monotonic() - t0) / 60.0, 1))
        camp.finish_round(row)
        log("imitation: " + json.dumps(row))
    return camp.state

"""Stage 1 by imitation: DAgger's settings (one config_dict), its campaign's files and the PPO fine-tune's config group.
Times in s, angles in rad."""
from __future__ import annotations

from ml_collections import config_dict

# a DAgger campaign's folder (dagger.Campaign): its state, its newest learner and its data
STATE = "state.json"
ARTIFACT = "getup_kneel_dagger.safetensors"
DATA = "data"
COLLECTED = "collected.json"


def default_config() -> config_dict.ConfigDict:
    return config_dict.create(
        rounds=15,     # which policy rolled each round out, from which starts, with which expert: the imitation
                       # stages of training/recipes/getup_keyframe.py
        # each round rolls the current policy out from this many fallen starts (seeds first_seed + round ·
        # starts_per_round …), disjoint from the evaluation's seeds 0 … eval_seeds − 1
        starts_per_round=32,
        first_seed=100_000,
        rollout_s=8.0,           # §4.8's gate must hold within 8 s
        # β: the share of segments in which the expert's takeover is what the robot does (DAgger's mixture),
        # beta_start · beta_decay^(round − 1); round 0 is the demonstrations alone
        beta_start=0.5,
        beta_decay=0.5,
        # the expert: from the robot's state at the start of every segment, the planner takes over for
        # takeover_replans replans (its own warm-start chain), each step of it a label; each replan's
        # candidates are the policy's own closed-loop rollout over the horizon and the expert's previous plan,
        # each with noisy copies (GPC: policy samples beside MPPI samples)
        expert=config_dict.create(
            takeover_replans=2,
            policy_samples=12,       # noisy copies of the policy's proposal
            plan_samples=12,         # noisy copies of the expert's previous plan
            horizon_s=0.5,
            # a robot past the first waypoint whose trunk falls below this [m] has fallen back to the floor:
            # its rise starts over at the first waypoint (a new attempt from where it lies, as a robot would),
            # not toward the kneel from the floor; 0 = never; the kneeling trunk is at ≈ 0.41 m, a lying one at
            # 0.03–0.22 m
            restart_below_m=0.25,
            # best-of-K in place of the takeovers (best_of_k.py; k 0 = the planner): from each start k rises of
            # the policy, all but the first with Gaussian target noise sigma_rad at knots knot_s apart; the first
            # that meets the gate labels every step of it up to the gate plus the hold; clean: only rises
            # without a failed getup attempt before the gate (common/events' rule) count
            best_of_k=config_dict.create(k=0, sigma_rad=0.1, knot_s=0.1, clean=False),
        ),
        # the fit: brax's tanh-normal policy MLP (the getup experts' network), MSE of tanh(loc) to the labels'
        # actions, warm-started from the previous round; Adam, the rate cosine-decayed to final_lr_share of it
        fit=config_dict.create(
            hidden_layer_sizes=[512, 256, 128],
            steps=6000,
            batch_size=1024,
            learning_rate=1e-3,
            final_lr_share=0.01,
            seed=0,
        ),
        eval_seeds=200,
        eval_seconds=8.0,
        seed=0,
    )


def finetune_config() -> config_dict.ConfigDict:
    """The PPO config's `imitation` group (RL from the imitation policy, finetune.py): the DAgger campaign whose
    data the BC term reads (its data/ rounds; "" = the campaign of the artifact the run starts from) and the
    planner's demonstrations its round 0 is (repository-relative or absolute), the first round it reads (0: the
    demonstrations and every round; k: rounds k … only, e.g. one expert's), and the term's schedule (bc_weight
    0 = none; decaying linearly to 0 over bc_decay_steps env steps; bc_batch pairs per loss)."""
    return config_dict.create(campaign="", demos="", first_round=0, bc_weight=0.0, bc_decay_steps=0, bc_batch=1024)

"""The seed's keyframe getup (§4.5–4.8): stage 1 rises from fallen to the kneel keyframe (task getup_kneel), stage
2 stands from the kneel (getup_stand), the gated full task goes on from stage 2 with fallen / kneeling / standing
starts (getup), then the energy (§4.7) and observation-noise (§4.6) fine-tunes. Not shipped: stage 1 does not
kneel yet, and the full task starts from stage 2 until it does.

Ours (why each, from the runs: training/LESSONS.md, the getup_keyframe rows): stage 1 learns by imitation of the
sampling planner (`python -m training.planner`), whose rise only its replanning holds: DAgger with the planner as
a closed-loop teacher on the learner's own states (training/imitation/, all 23 joints), then PPO from that policy
with a decaying behaviour-cloning term on the same planner data (DAPG; imitation/finetune.py), the seed's stage-1
reward plus the gate and a slope to its tilt, half of its episodes started along the whole of the planner's gated
rises (reference state initialisation, envs/starts/demos.py), sampling noise small enough for the rollouts to meet
the gate; no early end once a reached kneel sags (with positive rewards the policy learned not to reach the gate's
height, which arms it); the learning rate falls stage by stage as the rise holds (rise → rise_fine → rise_slow),
then the fallen starts widen to a bank far from the evaluation's seeds (rise_wide), then the BC term reads only
best-of-K rises of the policy itself (rise_best: the planner's labels meet the gate less often than the learner).
The campaign's rise went on from the policy DAgger's round 7 rolled out (a first PPO run at 0.1 std, 1.5 M steps
from round 6; kept in dagger/data/), not from the refitted learner a fresh run starts from; round 8 was rolled out
by rise_fine, rounds 9–11 by rise_slow from on-back starts only (where its rises failed), rounds 12–14 (best of 32)
by rise_wide from on-back starts.
Stage 2 learns along a reverse curriculum of starts from the kneel up the lunge (envs/starts/kneeling_path.py): the whole
path, its swing, the whole path again. The runtime's target rule R6 is in every stage."""
from training.recipe import Recipe, Stage

DEMOS = "training/campaigns/getup_keyframe/demos"
# pre-tanh sampling std 0.015 (≈ 0.03 rad of target noise at the getup action scale) and no entropy bonus: the gate
# asks for the trunk within 0.57° of vertical, which the rollouts meet under 0.03 rad of noise and never under 0.1
# (at std 0.1 PPO never saw the gate's reward); the BC term (10: at 1 PPO left the rise for the pose term's optimum
# on the floor) decays over the stage's steps; a critic-only warm-up first (a new critic under a trained policy)
RISE = {"ppo.imitation.demos": DEMOS, "ppo.imitation.bc_weight": 10.0, "ppo.imitation.bc_decay_steps": 20_000_000,
        "ppo.init_noise_std": 0.015, "ppo.value_warmup_steps": 500_000, "ppo.learning_rate": 1e-4,
        "ppo.entropy_cost": 0.0,
        "env.reward.scales.gate": 1.0, "env.reward.scales.upright": 1.0,
        "env.demo_starts.prob": 0.5, "env.demo_starts.folder": DEMOS, "env.demo_starts.window_s": 8.0,
        "env.demo_starts.gated_only": True}
# at that noise a step of 1e-4 moved the policy by 0.2–0.3 nats a PPO update, and the share the first 1.5 M steps
# raised fell back within the next 1 M: the rise stops there and goes on at a third of the rate, its critic kept
RISE_FINE = {**RISE, "ppo.learning_rate": 3e-5, "ppo.value_warmup_steps": 0}
# at 3e-5 the share still fell back after its first 1 M steps; at 1e-5 it rose and held (the BC term's line goes on)
RISE_SLOW = {**RISE_FINE, "ppo.learning_rate": 1e-5, "ppo.imitation.bc_weight": 8.0,
             "ppo.imitation.bc_decay_steps": 16_000_000}
# the default bank (128 fallen starts, seeds 0 …) is learnt start by start: on the back the share from its own seeds
# rose while that from seeds it never started from did not; 2048 starts from seeds far from the evaluation's
# (fallen seeds 0 … 999) generalise, and keep the evaluation held out; the stage ends at 6.0 M, its best checkpoint
# (half-way along the BC line)
RISE_WIDE = {**RISE_SLOW, "ppo.imitation.bc_weight": 6.0, "ppo.imitation.bc_decay_steps": 12_000_000,
             "env.fallen.bank_starts": 2048, "env.fallen.seed": 1_000_000}
# the planner's labels meet the gate less often than the learner from its own states (the teacher's own rises, 0.62
# of 200 fallen seeds against its 0.79): the BC term reads only the best-of-K rounds (12 …: its own rises that met
# the gate, from the on-back starts where its rises fail), the fallen starts and the rest as `rise_wide`; the stage
# ends at 1.5 M, its best checkpoint (0.80 of 200 seeds; 0.72–0.73 at 2.3 and 3.0 M)
RISE_BEST = {**RISE_WIDE, "ppo.imitation.campaign": "training/campaigns/getup_keyframe/dagger",
             "ppo.imitation.first_round": 12, "ppo.imitation.bc_weight": 3.0,
             "ppo.imitation.bc_decay_steps": 12_000_000}
# the roll (stage 0) from scratch on the back and side starts of a bank far from the evaluation's seeds; half of
# brax's sampling std (its full std throws the 2 rad-scale targets from limit to limit)
ROLL = {"ppo.policy_std_scale": 0.5, "env.fallen.bank_starts": 512, "env.fallen.seed": 2_000_000}
STAND = {"ppo.policy_std_scale": 0.25, "env.reverse_curriculum.max_progress": 2.0}
FULL = {"ppo.policy_std_scale": 0.25, "ppo.entropy_cost": 0.001, "ppo.learning_rate": 1e-4}
ENERGY = {**FULL, "env.reward.scales.energy": -0.01}

RECIPE = Recipe(
    name="getup_keyframe", policy="getup_keyframe",
    summary="the seed's keyframe getup through the kneel (not shipped until it kneels)",
    stages=(
        Stage("dagger", kind="imitation", steps=15),
        Stage("rise", task="getup_kneel", steps=1_495_040, init="dagger", config=RISE),
        Stage("rise_fine", task="getup_kneel", steps=4_014_080, init="rise", config=RISE_FINE),
        Stage("rise_slow", task="getup_kneel", steps=3_010_560, init="rise_fine", config=RISE_SLOW),
        Stage("rise_wide", task="getup_kneel", steps=6_021_120, init="rise_slow", config=RISE_WIDE),
        Stage("rise_best", task="getup_kneel", steps=1_515_520, init="rise_wide", config=RISE_BEST),
        Stage("roll", task="getup_roll", steps=10_000_000, config=ROLL),
        Stage("stand_path", task="getup_stand", steps=27_095_040, config=STAND),
        Stage("stand_swing", task="getup_stand", steps=7_024_640, init="stand_path",
              config={**STAND, "env.reverse_curriculum.min_progress": 1.0}),
        Stage("stand", task="getup_stand", steps=7_024_640, init="stand_swing", config=STAND),
        Stage("full", task="getup", steps=30_000_000, init="stand",
              config={**FULL, "ppo.value_warmup_steps": 1_500_000}),
        Stage("energy", task="getup", steps=10_000_000, init="full",
              config={**ENERGY, "ppo.value_warmup_steps": 500_000}),
        Stage("noise", task="getup", steps=10_000_000, init="energy", config={**ENERGY, "env.obs_noise_scale": 1.0}),
    ))

"""The seed's keyframe getup (§4.5–4.9) as a switched chain of three members: fallen → (roll →) kneel → stand.

Stages (each one line of why below; the runs behind each: training/LESSONS.md, the getup_keyframe rows):
- stage 1, the rise to the kneel (task getup_kneel): DAgger with the sampling planner as the expert
  (training/imitation/), then PPO from that policy with a decaying behaviour-cloning term on the campaign's data
  (DAPG), the seed's stage-1 reward plus §4.8's gate and a slope to its tilt, starts along the planner's gated
  rises (backplay); first at brax-scale sampling noise (rise_explore), then at noise small enough for the
  rollouts to meet the gate; the rate falls stage by stage (rise → rise_fine → rise_slow), the fallen starts
  widen (rise_wide), then the BC term reads best-of-K rises of the policy itself (rise_best). Between the PPO
  stages, DAgger rounds rolled out by the PPO policy so far join the same campaign (dagger_*), and the PPO
  stages after them read them.
- stage 0, the roll (task getup_roll, ours): from the back or side onto the front, where the rise is reliable;
  then with the side starts weighted up (roll_side); then the rise again, from where the roll hands over
  (rise_rolled).
- stage 2, the stand from the kneel (task getup_stand) along a reverse curriculum of starts up the lunge, then
  from the kneels the chain's rise really hands over (stand_band).
- the seed's energy fine-tune (§4.7) of each member: stand_energy, rise_energy, roll_energy; then the stand at five
  times the cost (stand_quiet, stand_still: it still chattered while standing); the rise's again from rise_rolled
  with a fifth of its starts where it has just failed (rise_retry, the student's teacher's rise: no better in the
  chain once a rise lying on its side goes back to the roll); the roll's with face-down starts too (roll_prone: some
  lie face down short of the rise's hand-over); best-of-K rounds of the energy-tuned rise that keep only rises
  without a failed attempt (dagger_clean), and the rise's BC term on them (rise_clean); the same rounds from where
  the roll hands over (dagger_handover), and the rise from them at twice the cost (rise_handover).
The runtime's target rule R6 is in every stage.
The members ship as a switched chain, not as one network: policies/getup_keyframe/ holds the three artifacts and
chain.json (common/keyframe_chain.py), which names them and the rise → stand hand-over; common/events.keyframe_stage
switches and latches roll → rise → stand, in training's evaluation, the simulator's and the runtime's chain mode.
"""
from training.recipes.base import Recipe, Stage

DEMOS = "training/campaigns/getup_keyframe/demos"
# the planner's takeovers as the expert, a robot that fell back not restarted (the restart rule came with best-of-K)
PLANNER = {"dagger.expert.restart_below_m": 0.0}
# best of 32 rises of the policy as the expert: the planner's labels met the gate less often than the learner
BEST_OF_K = {"dagger.expert.best_of_k.k": 32, "dagger.expert.best_of_k.sigma_rad": 0.05}
# sampling std 0.015 pre-tanh (≈ 0.03 rad of target noise): the gate asks for the trunk within 0.57° of vertical,
# which rollouts meet only under that little noise; the BC term keeps the rise while PPO finds the gate; a
# critic-only warm-up first (a new critic under a trained policy)
RISE = {"ppo.imitation.demos": DEMOS, "ppo.imitation.bc_weight": 10.0, "ppo.imitation.bc_decay_steps": 20_000_000,
        "ppo.init_noise_std": 0.015, "ppo.value_warmup_steps": 500_000, "ppo.learning_rate": 1e-4,
        "ppo.entropy_cost": 0.0,
        "env.reward.scales.gate": 1.0, "env.reward.scales.upright": 1.0,
        "env.demo_starts.prob": 0.5, "env.demo_starts.folder": DEMOS, "env.demo_starts.window_s": 8.0,
        "env.demo_starts.gated_only": True}
# at that noise the step must shrink with the std (LESSONS: period 3)
# the first PPO from the DAgger learner, at brax-scale sampling noise: where the small-noise stages start
RISE_EXPLORE = {**RISE, "ppo.init_noise_std": 0.1, "ppo.entropy_cost": 0.001}
RISE_FINE = {**RISE, "ppo.learning_rate": 3e-5, "ppo.value_warmup_steps": 0}
RISE_SLOW = {**RISE_FINE, "ppo.learning_rate": 1e-5, "ppo.imitation.bc_weight": 8.0,
             "ppo.imitation.bc_decay_steps": 16_000_000}
# 2048 fallen starts from seeds far from the evaluation's generalise where 128 are learnt start by start (period 4)
RISE_WIDE = {**RISE_SLOW, "ppo.imitation.bc_weight": 6.0, "ppo.imitation.bc_decay_steps": 12_000_000,
             "env.fallen.bank_starts": 2048, "env.fallen.seed": 1_000_000}
# the BC term reads only the best-of-K rounds (dagger_best's, 12 …): the policy's own rises that met the gate
# (period 8)
RISE_BEST = {**RISE_WIDE, "ppo.imitation.first_round": 12, "ppo.imitation.bc_weight": 3.0,
             "ppo.imitation.bc_decay_steps": 12_000_000}
# the roll (stage 0) from scratch on the back and side starts of a bank far from the evaluation's seeds; half of
# brax's sampling std (its full std throws the 2 rad-scale targets from limit to limit)
# (face down needs no roll: its starts are left out)
ROLL = {"ppo.policy_std_scale": 0.5, "env.fallen.bank_starts": 512, "env.fallen.seed": 2_000_000,
        "env.fallen.side_weights": [0, 1, 1]}
# the side starts (a twentieth of the bank) are where the chain's roll fails: weighted four times
ROLL_SIDE = {**ROLL, "env.fallen.side_weights": [0, 1, 4]}
# face-down starts too: a robot lying face down but short of the rise's hand-over (forward axis between −0.5 and
# −0.8 down) starts with the roll, which had never seen such a start and lay still (3 of 1000 held-back falls)
ROLL_PRONE = {**ROLL_SIDE, "env.fallen.side_weights": [1, 1, 4]}
# the rise from where the roll hands it over as well as from face-down falls: in the chain the rise only ever
# starts face down, and its on-back misses are rises that fail from the roll's hand-over (period 3)
RISE_ROLLED = {**RISE_BEST, "env.rolled_starts.prob": 0.3, "env.rolled_starts.roll_policy": "@getup_keyframe/roll_side",
               "env.fallen.side_weights": [1, 0, 0]}
# the rise, before and after its energy fine-tune, lay still face down after a miss in 3 % of held-back falls (its
# next attempt pays only seconds later, lying still at once): a fifth of its starts where the rise has just failed,
# so that trying again is paid from an episode's first step (ships as a chain, period 3)
RETRY = {"env.fell_back.prob": 0.2, "env.fell_back.rise_policy": "@getup_keyframe/rise_rolled",
         "env.fell_back.roll_policy": "@getup_keyframe/roll_side", "env.demo_starts.prob": 0.3}
STAND = {"ppo.policy_std_scale": 0.25, "env.reverse_curriculum.max_progress": 2.0}
# half the stand's starts where the chain's rise hands over (the kneel band's first tick, or §4.8's gate's), with
# the rise's velocities: the stand fell from 2.9° kneels it had never started from (a hand-over at the band: 0.86)
STAND_BAND = {**STAND, "env.rise_kneels.prob": 0.5, "env.rise_kneels.rise_policy": "@getup_keyframe/rise_rolled",
              "env.rise_kneels.roll_policy": "@getup_keyframe/roll_side"}
# the seed's last step (§4.7): the energy cost Σ|q̇·τ/τmax| after height and pose, at the weight that quieted the
# baseline's hops; a critic warm-up first (the return gained a term)
ENERGY_COST = {"env.reward.scales.energy": -0.01, "ppo.value_warmup_steps": 300_000}
# at that weight the stand still chattered (534 W standing; the cost was 0.35 of the 2.0 a step pays): five times
# the weight, so that the chatter costs most of what standing pays
QUIET = {**ENERGY_COST, "env.reward.scales.energy": -0.05}
# a third of the chain's stand-ups came after the rise fell back to the floor once (1.62 attempts per fall, period
# 3): best of 32 rises of the energy-tuned rise from face-down falls, only those without a failed attempt
CLEAN_BEST_OF_K = {**BEST_OF_K, "dagger.expert.best_of_k.clean": True}
# the BC term reads only those rounds (15 …): the rise in one go
RISE_CLEAN = {**RISE_ROLLED, **ENERGY_COST, "ppo.value_warmup_steps": 0, "ppo.imitation.first_round": 15}
# on the back and side the chain's extra attempts are rises that fall back from the roll's hand-over, where no
# round had started (period 4): best-of-K rounds from there too, the BC term on all clean rounds (15 …), 0.4 of the
# starts at the shipped roll's hand-overs (0.4 demo windows, 0.2 face-down falls), and twice §4.7's weight (energy
# to stand was 1.003× the baseline's)
RISE_HANDOVER = {**RISE_CLEAN, "env.rolled_starts.prob": 0.4, "env.demo_starts.prob": 0.4,
                 "env.rolled_starts.roll_policy": "@getup_keyframe/roll_prone",
                 "env.reward.scales.energy": 2 * ENERGY_COST["env.reward.scales.energy"],
                 "ppo.value_warmup_steps": ENERGY_COST["ppo.value_warmup_steps"]}

RECIPE = Recipe(
    name="getup_keyframe", policy="getup_keyframe",
    summary="the seed's keyframe getup through the kneel: roll, rise, stand, shipped as a switched chain",
    stages=(
        Stage("dagger", kind="imitation", steps=7, config=PLANNER),
        # its 1.5 M checkpoint rose most before the rise was lost at that noise (LESSONS: period 2)
        Stage("rise_explore", task="getup_kneel", steps=20_000_000, end_at=1_495_040, init="dagger",
              config=RISE_EXPLORE),
        # labels on the states the PPO policy visits (DAgger on the learner that goes on)
        Stage("dagger_explore", kind="imitation", steps=1, continues="dagger", policy="rise_explore",
              config=PLANNER),
        # the policy the round was rolled out by, under a new critic and the small noise
        Stage("rise", task="getup_kneel", steps=1_495_040, init="rise_explore", init_artifact=True, config=RISE),
        # its 4.0 M checkpoint, before the rate fell (period 3)
        Stage("rise_fine", task="getup_kneel", steps=20_000_000, end_at=4_014_080, init="rise", config=RISE_FINE),
        Stage("dagger_fine", kind="imitation", steps=1, continues="dagger", policy="rise_fine", config=PLANNER),
        Stage("rise_slow", task="getup_kneel", steps=3_010_560, init="rise_fine", config=RISE_SLOW),
        # labels where the on-back rises fail (period 5)
        Stage("dagger_back", kind="imitation", steps=3, continues="dagger", policy="rise_slow", lying="on_back",
              config=PLANNER),
        Stage("rise_wide", task="getup_kneel", steps=6_021_120, init="rise_slow", config=RISE_WIDE),
        Stage("dagger_best", kind="imitation", steps=3, continues="dagger", policy="rise_wide", lying="on_back",
              config=BEST_OF_K),
        # its 1.5 M checkpoint, the best of the run's four (period 8)
        Stage("rise_best", task="getup_kneel", steps=3_031_040, end_at=1_515_520, init="rise_wide",
              config=RISE_BEST),
        Stage("roll", task="getup_roll", steps=2_007_040, config=ROLL),
        Stage("roll_side", task="getup_roll", steps=1_515_520, init="roll", config=ROLL_SIDE),
        Stage("rise_rolled", task="getup_kneel", steps=6_062_080, init="rise_best", config=RISE_ROLLED),
        Stage("stand_path", task="getup_stand", steps=27_095_040, config=STAND),
        Stage("stand_swing", task="getup_stand", steps=7_024_640, init="stand_path",
              config={**STAND, "env.reverse_curriculum.min_progress": 1.0}),
        Stage("stand", task="getup_stand", steps=7_024_640, init="stand_swing", config=STAND),
        # the ship campaign's stages end at the checkpoint where its first period's CPU time ended (LESSONS: ships
        # as a chain, period 1)
        Stage("stand_band", task="getup_stand", steps=4_014_080, end_at=819_200, init="stand", config=STAND_BAND),
        # the energy fine-tune of each member, stand first (612 W while standing still), then the rise and the roll
        Stage("stand_energy", task="getup_stand", steps=3_010_560, end_at=1_208_320, init="stand_band",
              config={**STAND_BAND, **ENERGY_COST}),
        Stage("stand_quiet", task="getup_stand", steps=6_021_120, init="stand_energy", config={**STAND_BAND, **QUIET}),
        # the same, on from it (its standing power still fell at 6 M); it ends where its period's CPU time ended
        Stage("stand_still", task="getup_stand", steps=6_021_120, end_at=3_440_640, init="stand_quiet",
              config={**STAND_BAND, **QUIET, "ppo.value_warmup_steps": 0}),
        Stage("rise_energy", task="getup_kneel", steps=3_010_560, end_at=1_208_320, init="rise_rolled",
              config={**RISE_ROLLED, **ENERGY_COST}),
        Stage("rise_retry", task="getup_kneel", steps=3_010_560, init="rise_rolled",
              config={**RISE_ROLLED, **ENERGY_COST, **RETRY}),
        Stage("roll_energy", task="getup_roll", steps=1_505_280, end_at=921_600, init="roll_side",
              config={**ROLL_SIDE, **ENERGY_COST}),
        Stage("roll_prone", task="getup_roll", steps=1_505_280, init="roll_energy",
              config={**ROLL_PRONE, **ENERGY_COST}),
        Stage("dagger_clean", kind="imitation", steps=4, continues="dagger", policy="rise_energy", lying="face_down",
              config=CLEAN_BEST_OF_K),
        Stage("rise_clean", task="getup_kneel", steps=6_021_120, init="rise_energy", config=RISE_CLEAN),
        Stage("dagger_handover", kind="imitation", steps=4, continues="dagger", policy="rise_clean",
              rolled_by="roll_prone", config=CLEAN_BEST_OF_K),
        Stage("rise_handover", task="getup_kneel", steps=6_021_120, init="rise_clean", config=RISE_HANDOVER),
    ),
    # what ships (recipe --ship): the energy-tuned members, the stand the quiet one, the roll the one that also
    # turns a face-down robot the rest of the way, the rise the one cloned toward rises in one go from falls and
    # from the roll's hand-overs (fewest attempts and least energy to stand); the rise hands over at §4.8's gate,
    # where they stand most (LESSONS: ships as a chain, periods 1–5)
    chain={"roll": "roll_prone", "rise": "rise_handover", "stand": "stand_still"}, handover="kneel_gate")

"""The seed's keyframe getup (§4.5–4.8): stage 1 rises from fallen to the kneel keyframe (task getup_kneel), stage
2 stands from the kneel (getup_stand), the gated full task goes on from stage 2 with fallen / kneeling / standing
starts (getup), then the energy (§4.7) and observation-noise (§4.6) fine-tunes. Not shipped: stage 1 does not
kneel yet, and the full task starts from stage 2 until it does.

Ours (why each, from the runs: training/LESSONS.md, the getup_keyframe rows): stage 1 learns by backplay from the
sampling planner's rises to the kneel (`python -m training.planner`; envs/starts/demos.py): its episodes start
on the rises that met §4.8's gate, at most window_s before their end, the window widened stage by stage once
ADVANCE_AT of the evaluation's episodes meet the gate, then half of them from the loop's fallen starts; it acts
in the sagittal, mirrored action space (envs/sagittal.py), is paid for the gate and for a slope to its tilt, and
an episode whose reached kneel sags 3 cm ends. Stage 2 learns along a reverse curriculum of starts from the kneel
up the lunge (envs/starts/kneeling_path.py): the whole path, its swing, the whole path again. The runtime's
target rule R6 is in every stage."""
from training.recipe import Recipe, Stage

DEMOS = "training/campaigns/getup_keyframe/demos"
# exploration 0.15 of brax's (≈ 0.2 rad of target noise per step): the gate asks for the trunk within 0.57° of
# vertical, and brax's own std (≈ 1.3 rad at this action scale) throws a kneeling robot about
BACKPLAY = {"env.demo_starts.prob": 1.0, "env.demo_starts.folder": DEMOS, "env.demo_starts.gated_only": True,
            "env.reward.scales.gate": 1.0, "env.reward.scales.upright": 1.0, "env.drop_below_gate_m": 0.03,
            "env.action_space": "sagittal", "ppo.policy_std_scale": 0.15}
ADVANCE_AT = ("eval/episode_gate_reached", 0.8)   # share of evaluation episodes that met the gate
STAND = {"ppo.policy_std_scale": 0.25, "env.reverse_curriculum.max_progress": 2.0}
FULL = {"ppo.policy_std_scale": 0.25, "ppo.entropy_cost": 0.001, "ppo.learning_rate": 1e-4}
ENERGY = {**FULL, "env.reward.scales.energy": -0.01}

RECIPE = Recipe(
    name="getup_keyframe", policy="getup_keyframe",
    summary="the seed's keyframe getup through the kneel (not shipped until it kneels)",
    stages=(
        Stage("rise_near", task="getup_kneel", steps=10_000_000, advance_at=ADVANCE_AT,
              config={**BACKPLAY, "env.demo_starts.window_s": 0.5}),
        Stage("rise_mid", task="getup_kneel", steps=10_000_000, init="rise_near", advance_at=ADVANCE_AT,
              config={**BACKPLAY, "env.demo_starts.window_s": 2.0}),
        Stage("rise_floor", task="getup_kneel", steps=20_000_000, init="rise_mid",
              config={**BACKPLAY, "env.demo_starts.prob": 0.5, "env.demo_starts.window_s": 8.0}),
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

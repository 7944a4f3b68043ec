"""The student's teacher getup expert: the seed's gated full-task rewards (§4.8, per-step gate) fine-tuned
from the reward-only baseline (not the seed's stage-1/stage-2 curriculum: it rarely kneels), the energy
fine-tune (§4.7), then fallen starts replaced by landings of the joystick expert knocked over by a push."""
from training.recipes.base import Recipe, Stage

GATED = {"ppo.policy_std_scale": 0.125, "ppo.entropy_cost": 0.0, "ppo.learning_rate": 1e-4}
ENERGY = {**GATED, "env.reward.scales.energy": -0.01, "ppo.value_warmup_steps": 500_000}
TEACHER_JOYSTICK = "policies/joystick_handover/joystick_handover.safetensors"

RECIPE = Recipe(
    name="getup_knockdown", policy="getup_knockdown",
    summary="gated full-task getup from the baseline, energy-tuned, trained on knockdown landings (the student's "
            "teacher member; it does not kneel)",
    stages=(
        # the seed's gated rewards from a policy that already stands (`getup_full_from_baseline_pergate`)
        Stage("gated", task="getup", steps=7_024_640, init="@getup_baseline/energy",
              config={**GATED, "ppo.value_warmup_steps": 1_000_000}),
        Stage("energy", task="getup", steps=9_543_680, init="gated", config=ENERGY),   # `getup_keyframe_energy`
        # the states the teacher hands over after a push, then a bank of them (`getup_knockdown`, `getup_kd_bank`)
        Stage("knockdown", task="getup", steps=6_533_120, init="energy",
              config={**ENERGY, "env.knockdown_starts.prob": 0.5,
                      "env.knockdown_starts.joystick_policy": TEACHER_JOYSTICK}),
        Stage("landing_bank", task="getup", steps=5_529_600, init="knockdown", envs=1024,
              config={**ENERGY, "env.knockdown_starts.prob": 0.8, "env.knockdown_starts.bank_starts": 1024,
                      "env.knockdown_starts.seed": 300_000,
                      "env.knockdown_starts.joystick_policy": TEACHER_JOYSTICK}),
    ))

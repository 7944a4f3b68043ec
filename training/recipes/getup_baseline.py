"""The reward-only baseline getup (the seed's HO reward, §4.3), from scratch: the comparison of Table 4.3 and
the baseline composite of chapter 6. After the first stage, the sampling noise is narrowed in two steps, the
discount raised to 0.99, a standing-start share added and a small energy cost (ours, stated in its card)."""
from training.recipes.base import Recipe, Stage

QUIET = {"ppo.policy_std_scale": 0.125, "ppo.entropy_cost": 0.0}

RECIPE = Recipe(
    name="getup_baseline", policy="getup_baseline",
    summary="reward-only baseline getup (Table 4.3's comparison, the chapter-6 baseline composite)",
    stages=(
        # the seed's reward alone, from scratch (LESSONS.md: `getup_baseline`)
        Stage("reward_only", task="getup_baseline", steps=40_140_800, config={"ppo.policy_std_scale": 0.5}),
        # narrower sampling noise, then none from entropy: a stand that holds still (`getup_baseline_std025`,
        # `getup_baseline_quiet`)
        Stage("narrow", task="getup_baseline", steps=9_031_680, init="reward_only",
              config={"ppo.policy_std_scale": 0.25}),
        Stage("quiet", task="getup_baseline", steps=15_052_800, init="narrow", config=QUIET),
        # a longer horizon, standing starts, then the energy cost (`getup_baseline_g099`, `_stand`, `_energy`)
        Stage("discount", task="getup_baseline", steps=5_529_600, init="quiet",
              config={**QUIET, "ppo.discounting": 0.99, "ppo.value_warmup_steps": 500_000}),
        Stage("stand", task="getup_baseline", steps=10_547_200, init="discount",
              config={**QUIET, "ppo.discounting": 0.99, "ppo.value_warmup_steps": 500_000,
                      "env.start_probs": [0.8, 0.0, 0.2]}),
        Stage("energy", task="getup_baseline", steps=13_557_760, init="stand",
              config={**QUIET, "ppo.discounting": 0.99, "ppo.value_warmup_steps": 500_000,
                      "env.start_probs": [0.8, 0.0, 0.2], "env.reward.scales.energy": -0.01}),
    ))

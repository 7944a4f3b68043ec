"""The joystick expert: MuJoCo Playground's T1 joystick recipe (domain randomisation on), then two fine-tunes
that weigh and sharpen yaw-rate tracking (to reach evaluation/joystick.py's yaw-rate target)."""
from training.recipes.base import Recipe, Stage

RECIPE = Recipe(
    name="joystick", policy="joystick",
    summary="joystick expert: walk and turn on command (the baseline composite's upright member)",
    stages=(
        Stage("walk", task="joystick", steps=109_117_440),   # Playground's recipe (LESSONS.md: `joystick`)
        # yaw-rate tracking weighed up, then a sharper tracking kernel (`joystick_yaw`, `joystick_sharp`)
        Stage("yaw", task="joystick", steps=20_971_520, init="walk",
              config={"env.reward.scales.tracking_ang_vel": 1.0}),
        Stage("sharp", task="joystick", steps=13_107_200, init="yaw",
              config={"env.reward.scales.tracking_ang_vel": 1.0, "env.reward.tracking_sigma": 0.1}),
    ))

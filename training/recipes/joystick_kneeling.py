"""The kneeling teacher's joystick expert: the shipped `joystick_handover` (which catches the knockdown getup's
rise) fine-tuned with half of its episodes starting where the keyframe chain's stand hands over at the waist
switch: the lunge out of the kneel, which a squat-up never makes."""
from training.recipes.base import Recipe, Stage

JOYSTICK = "policies/joystick_handover/joystick_handover.safetensors"
# the members the getup_keyframe recipe's chain names; the rise hands over to the stand at the kneel band (the
# default of env.handover.up_error), as in the student's labels
CHAIN = {"env.handover.prob": 0.5, "env.handover.getup_policy": "@getup_keyframe/stand_still",
         "env.handover.rise_policy": "@getup_keyframe/rise_energy",
         "env.handover.roll_policy": "@getup_keyframe/roll_energy"}
# joystick_handover's rewards (the joystick recipe's sharp yaw-rate tracking)
SHARP = {"env.reward.scales.tracking_ang_vel": 1.0, "env.reward.tracking_sigma": 0.1}
# from an artifact (its run is not kept): a new critic under the trained policy first, then PPO at a sampling std
# (pre-tanh) and a rate that keep the walk
FROM_ARTIFACT = {"ppo.init_noise_std": 0.3, "ppo.value_warmup_steps": 1_000_000, "ppo.learning_rate": 1e-4}

RECIPE = Recipe(
    name="joystick_kneeling", policy="joystick_kneeling",
    summary="joystick expert that catches the keyframe chain's stand at the waist switch (the kneeling teacher's)",
    stages=(
        Stage("kneeling", task="joystick", steps=10_035_200, init=JOYSTICK, init_artifact=True,
              config={**SHARP, **CHAIN, **FROM_ARTIFACT}),
    ))

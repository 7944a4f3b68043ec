"""The student's teacher joystick expert: the joystick expert fine-tuned with half of its episodes starting
where a getup expert's rise hands over (the waist passing the switch height), so that it catches the lunge."""
from training.recipes.base import Recipe, Stage

RECIPE = Recipe(
    name="joystick_handover", policy="joystick_handover",
    summary="joystick expert that also catches the getup expert's hand-over (the student's teacher member)",
    stages=(
        # catch the getup expert's rise where the teacher hands it over (LESSONS.md: `joystick_handover_gpu`)
        Stage("handover", task="joystick", steps=41_123_840, init="@joystick/sharp",
              config={"env.reward.scales.tracking_ang_vel": 1.0, "env.reward.tracking_sigma": 0.1,
                      "env.handover.prob": 0.5, "env.handover.getup_policy": "@getup_knockdown/energy"}),
    ))

"""The student that gets up through the kneel: one network distilled by DAgger (the seed's Table 5.2 settings, the
unified env) from the kneeling teacher, the keyframe chain (roll, rise, stand; getup_keyframe's members) below the
0.5 m waist switch and the joystick expert that catches its lunge (joystick_kneeling) above.
Ours beside the seed: a β floor, so that every phase's data keeps the teacher's states (brax's bc fits only the
newest phase's data: without it the student forgot the stand), and the chain's labels handed over to the stand
at the kneel band (2.9°), a kneel the memoryless student can tell from one still rising, where at §4.8's gate
(0.57°) the latched chain labels the same still kneel "hold" and "stand up" (LESSONS: getup_keyframe, the chain as
one network, periods 2–5). It ships as policies/student/ once it loses no target of today's student; until then
under its own name."""
from training.recipes.base import Recipe, Stage

# the rise is rise_retry (a fifth of its starts where a rise has just failed), not the shipped chain's
# rise_handover: with that one as the teacher from phase 1500 the student lost the kneel by phase 1900 and
# standing by 2300 (LESSONS: the kneeling teacher, period 5)
TEACHER = {"roll": "@getup_keyframe/roll_prone", "rise": "@getup_keyframe/rise_retry",
           "stand": "@getup_keyframe/stand_still", "joystick": "@joystick_kneeling/kneeling"}
# β from 1 to its floor over the first 300 phases; evaluations every 100 phases
DAGGER = {"bc.beta_floor": 0.3, "bc.beta_decay_phases": 300, "bc.handover_up_error": 0.05, "bc.num_evals": 35}

RECIPE = Recipe(
    name="student_kneeling", policy="student_kneeling",
    summary="the student distilled from the keyframe chain below the waist switch, the joystick expert above",
    stages=(
        Stage("dagger", kind="distill", steps=3400, envs=1024, teacher=TEACHER, config=DAGGER),
    ))

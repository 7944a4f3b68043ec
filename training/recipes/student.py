"""The student: one network distilled by DAgger (Table 5.2 settings, the unified env) from the stitched
teacher (getup expert below the 0.5 m waist switch, joystick expert above), then continued with knockdown
pushes and wall-course episodes (ours): DAgger-3400, the walls stage's 400 phases.
`finetune` (training/distill/finetune.py), what ships: PPO on the unified env's "skills" reward from
those DAgger weights, critic warm-up first, a behaviour-cloning term toward the same teacher that decays over
30 M steps (held in wall-course episodes; the stage stops at 3 M), starts mixing fallen, kneeling and standing
states, knockdowns and the push test's torso shoves, and the low-wall course (CARD.md)."""
from training.recipes.base import Recipe, Stage

JOYSTICK = "policies/joystick_handover/joystick_handover.safetensors"
GETUP = "policies/getup_knockdown/getup_knockdown.safetensors"
KNOCKDOWN = {"env.knockdown.prob": 0.25}
# the stage stops at 3 M steps, where the fine-tune is best on the walls (later it stands at them: LESSONS.md,
# "student / finetune"); BC decays on a 30 M schedule, so it still weighs 0.9 at the stage's end
FINETUNE_STEPS = 3_010_560
BC_DECAY_STEPS = 30_000_000
FINETUNE = {
    # a failed rise costs about 65 steps of walking reward (at 1, 13): under γ 0.97 the delay it causes lies
    # past the horizon, so the cost itself must price the drop
    "env.reward.mode": "skills", "env.reward.getup.failed_rise_cost": 5.0,
    "env.knockdown.prob": 0.5, "env.knockdown.shove": "mixed", "env.walls.prob": 0.2,
    # walls met at walking speed, as in the loop's test; there the teacher's trip-and-getup stays the target
    # (distill/finetune.py), and ground banked by a fall across the wall pays through the getup beyond it
    # (unified.py's course term: 10 per m, about 4 per s at the held command, above a getup's loss)
    "env.wall_course.approach_m": [1.0, 5.0], "ppo.teacher.bc_hold_in_course": True,
    "env.reward.course.progress_weight": 10.0,
    # nearly every extra attempt at a wall is a rise that reaches the switch and drops back before it stands:
    # the walk pays only once the getup has stood up (unified.py), a hand-over that waits for a settled rise
    "env.reward.walk_after_stand_up": True,
    # the mean is the DAgger student's; PPO samples ±0.05 action units (0.1 rad) around it at first
    "ppo.policy_distribution": "normal", "ppo.init_noise_std": 0.05, "ppo.entropy_cost": 0.0,
    "ppo.learning_rate": 1e-4, "ppo.value_warmup_steps": 1_000_000,
    "ppo.teacher.bc_weight": 1.0, "ppo.teacher.bc_decay_steps": BC_DECAY_STEPS}

RECIPE = Recipe(
    name="student", policy="student",
    summary="the distilled student the runtime runs (walk, fall, get up) under the safety supervisor",
    stages=(
        # DAgger from the stitched teacher, then with knockdown pushes, then with the wall course
        # (LESSONS.md: `student_handover`, `student_knockdown`, `student_walls`)
        Stage("handover", kind="distill", steps=1600, envs=1024,
              teacher={"getup": "@getup_knockdown/energy", "joystick": JOYSTICK},
              config={"bc.num_evals": 21}),
        Stage("knockdown", kind="distill", steps=1400, envs=1024, init="handover",
              teacher={"getup": "@getup_knockdown/energy", "joystick": JOYSTICK},
              config={**KNOCKDOWN, "bc.num_evals": 8}),
        Stage("walls", kind="distill", steps=400, envs=1024, init="knockdown",
              teacher={"getup": GETUP, "joystick": JOYSTICK},
              config={**KNOCKDOWN, "env.walls.prob": 0.2, "bc.num_evals": 5}),
        # PPO on its own outcomes toward the same teacher (`student` / `finetune`)
        Stage("finetune", task="unified", steps=FINETUNE_STEPS, init="walls",
              teacher={"getup": GETUP, "joystick": JOYSTICK}, config=FINETUNE),
    ))

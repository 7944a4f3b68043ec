"""The student: one network distilled by DAgger (Table 5.2 settings, the unified env) from the stitched
teacher (getup expert below the 0.5 m waist switch, joystick expert above), then continued with knockdown
pushes and wall-course episodes (ours). The shipped phase is DAgger-3400: the walls stage's 400 phases."""
from training.recipe import Recipe, Stage

JOYSTICK = "policies/joystick_handover/joystick_handover.safetensors"
KNOCKDOWN = {"env.knockdown.prob": 0.25}

RECIPE = Recipe(
    name="student", policy="student",
    summary="the distilled student the runtime runs (walk, fall, get up) under the safety supervisor",
    stages=(
        Stage("handover", kind="distill", steps=1600, envs=1024,
              teacher={"getup": "@getup_knockdown/energy", "joystick": JOYSTICK},
              config={"bc.num_evals": 21}),
        Stage("knockdown", kind="distill", steps=1400, envs=1024, init="handover",
              teacher={"getup": "@getup_knockdown/energy", "joystick": JOYSTICK},
              config={**KNOCKDOWN, "bc.num_evals": 8}),
        Stage("walls", kind="distill", steps=400, envs=1024, init="knockdown",
              teacher={"getup": "policies/getup_knockdown/getup_knockdown.safetensors", "joystick": JOYSTICK},
              config={**KNOCKDOWN, "env.walls.prob": 0.2, "bc.num_evals": 5}),
    ))

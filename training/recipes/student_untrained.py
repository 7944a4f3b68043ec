"""The untrained student placeholder: the student's network shape with seeded random weights, manifest
`trained: false`. What `make demo` runs when no trained student is shipped, and the tests' runtime policy."""
from training.recipes.base import Recipe, Stage

RECIPE = Recipe(
    name="student_untrained", policy="student_untrained",
    summary="random-init placeholder with the student's shape (NOT TRAINED: plumbing and tests)",
    stages=(Stage("random_init", kind="random_init"),))

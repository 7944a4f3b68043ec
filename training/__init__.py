"""Training side of the T1 project: MJX/CPU envs, PPO, distillation, imitation and the recipes that make the
shipped policies. Packages by role, each importing only those before it: envs ← core ← export ← planner ←
evaluation ← distill ← imitation ← ppo ← recipes ← cli.py (training/README.md, tests/test_layers.py)."""

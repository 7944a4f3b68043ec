"""Training side of the T1 project: the one observation definition (common/observation.py), policy
artifacts (common/artifact.py: write/read/validate), export from brax (training/export.py); MJX envs,
PPO, teacher and DAgger come later."""

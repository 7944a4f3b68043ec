"""PPO runs: the trainer (train.py), its configs (configs.py), which extension a run gets (extensions.py), old
run states read back (migration.py) and a stage-1 run's per-checkpoint kneel report (kneel_report.py)."""

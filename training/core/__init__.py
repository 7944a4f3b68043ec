"""What every PPO-side package builds on: checkpoints and run states (checkpoints.py), learning curves (curves.py),
`--config key=value` (overrides.py), the policy/value networks (networks.py), the one interface a run's extension
implements (extension.py) and the physics backend a run defaults to (backend.py). Imports only training.envs."""

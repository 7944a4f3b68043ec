"""Policy artifacts from training: brax PPO params → the runtime's safetensors (brax.py), an untrained
student's artifact (untrained.py). Imports training.core and training.envs."""

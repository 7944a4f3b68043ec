"""Distilling teachers into the student: the teachers (teacher.py), DAgger (dagger.py) and the student's PPO
fine-tune with its BC term (finetune.py, a training.core.extension.PPOExtension)."""

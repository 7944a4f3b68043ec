"""Evaluating artifacts in the envs: the getup batch (batch.py, its CPU rollout cpu.py, the thesis' Table 4.3
in table_4_3.py), the joystick's tracking metrics (joystick.py), and how an artifact acts (artifact_policy.py)."""

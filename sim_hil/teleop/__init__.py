"""Gamepad / keyboard teleop for the T1 runtime (python -m sim_hil.teleop); see __main__.py."""

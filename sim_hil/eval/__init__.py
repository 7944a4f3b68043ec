"""Evaluation in the loop (the seed's chapter 6 as commands): `python -m sim_hil.eval <scenario> ...`.

Kept import-light on purpose: training/ imports sim_hil.eval.events (numpy only) without LCM or MuJoCo.
"""

"""Evaluation in the loop (the seed's chapter 6 as commands): `python -m sim_hil.eval <scenario> ...`. What fallen,
standing and the kneel gate mean lives below both the simulator and training, in common/events.py."""

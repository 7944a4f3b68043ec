"""sim_hil: the simulated Booster T1 speaking the robot's own bus (see sim_hil/sim.py for the tick)."""

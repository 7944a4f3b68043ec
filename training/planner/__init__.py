"""Rises to the kneel found by a sampling planner on the training physics (the kneel-by-demonstration method).

Stage 1 by PPO from the floor never reached the kneel (training/LESSONS.md, getup_keyframe periods 1–6): the
learner lacked a feasible motion. Here model-predictive path integral control (MPPI) searches joint-target
plans on the project's batched C physics (`training/envs/cpu_backend.py`: the firmware motor law and rule R6
at every 2 ms substep, the shared PD gains, the getup env's collision model), from the loop's fallen starts
after PREPARE, toward the kneel keyframe and the seed's §4.8 gate. Its demonstrations (states, targets,
observations) are what stage 1 starts from and learns toward.

config.py  the settings (one config_dict);   costs.py  the cost terms, small named functions;
mppi.py    the planner;  keyframes.py  its waypoints;  demos.py  a demonstration on disk, the report, figures;
__main__   `python -m training.planner`.
"""

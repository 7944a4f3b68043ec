"""Rises to the kneel found by a sampling planner on the training physics: the stage-1 expert.

Model-predictive path integral control (MPPI) searches joint-target plans on the project's batched C physics
(`training/envs/cpu_backend.py`: the firmware motor law and rule R6 at every 2 ms substep, the shared PD gains, the
getup tasks' collision model), from the loop's fallen starts after PREPARE, toward the kneel keyframe and the seed's
§4.8 gate. Its stored rises (states, targets, observations) are round 0 of DAgger's data and the starts of
backplay; training/imitation/ asks it for labels on the learner's own states.

config.py  the settings (one config_dict);   costs.py  the cost terms, small named functions;
mppi.py    the planner;  keyframes.py  its waypoints;  demos.py  a demonstration on disk, the report, figures;
__main__   `python -m training.planner`.
"""

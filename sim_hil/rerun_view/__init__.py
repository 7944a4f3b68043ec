"""Runs in Rerun: the robot in 3-D with its signals on one timeline, from any LCM log (convert.py, `python -m
sim_hil.lcmlog rerun`) and live from the LCM group (live.py, `make demo VIEW=rerun`). record.py maps the
project's messages to entities, robot.py draws the model's geoms, blueprint.py is the shipped layout."""

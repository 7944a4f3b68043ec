"""The layout shipped with every recording: the robot in 3-D over the runtime's events on the left; joint
angles (measured against commanded), joint torques, joystick against trunk velocity and the loop's timing
on the right. The joints shown are plot.py's defaults (the left leg's pitch chain)."""
from __future__ import annotations

import rerun.blueprint as rrb

from sim_hil.lcmlog.plot import DEFAULT_JOINTS
from sim_hil.rerun_view.record import EVENTS, joint_entity
from sim_hil.rerun_view.robot import GEOMS_PATH, TRUNK_GEOM

# the 3-D camera: in front and to the right of a standing robot, looking at its waist [m]; it follows the trunk
EYE_POSITION_M = (1.6, -1.6, 1.0)
EYE_TARGET_M = (0.0, 0.0, 0.45)


def blueprint(joints=DEFAULT_JOINTS) -> rrb.Blueprint:
    angles = [joint_entity(j, leaf) for j in joints for leaf in ("q", "q_des")]
    torques = [joint_entity(j, "tau_est") for j in joints]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.Spatial3DView(name="robot", origin="/", contents=f"{GEOMS_PATH}/**",
                                  eye_controls=rrb.EyeControls3D(position=EYE_POSITION_M, look_target=EYE_TARGET_M,
                                                                 eye_up=(0, 0, 1),
                                                                 tracking_entity=f"{GEOMS_PATH}/{TRUNK_GEOM}")),
                rrb.TextLogView(name="mode, faults, refusals", origin=EVENTS),
                row_shares=[3, 1]),
            rrb.Vertical(
                rrb.TimeSeriesView(name="joint angles: q vs q_des [rad]", contents=angles),
                rrb.TimeSeriesView(name="joint torques [N·m]", contents=torques),
                rrb.TimeSeriesView(name="joystick vs trunk velocity",
                                   contents=["command/joystick", "trunk/velocity"]),
                rrb.TimeSeriesView(name="loop timing [us]", origin="runtime/timing"),
            ),
            column_shares=[3, 2]),
        collapse_panels=True)

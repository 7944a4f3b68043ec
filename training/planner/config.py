"""The rise planner's settings, one config_dict (Playground style). Times in s, angles in rad, heights in m."""
from __future__ import annotations

from ml_collections import config_dict

from common import events


def default_config() -> config_dict.ConfigDict:
    return config_dict.create(
        samples=64,              # rollouts per plan (rollout 0 is the current plan itself)
        horizon_s=0.7,           # how far each plan looks ahead
        knot_dt_s=0.1,           # spacing of the plan's PD-target knots; targets linear in between
        replan_every_s=0.1,      # how much of a plan runs before the next one (a whole number of knots)
        temperature=0.05,        # MPPI λ as a share of the rollouts' cost spread (small: near the best)
        max_seconds=8.0,         # a rise that has not met the gate by then has failed (the report counts 6 s too)
        hold_s=1.0,              # after the gate first holds, keep balancing this long (the demonstration's end)
        # exploration [rad]: large to rise off the floor, small to balance once near the kneel (the probe:
        # σ 0.3 rises, σ ≤ 0.1 balances); `near` switches with the kneel's trunk height within near_m
        sigma_rise_rad=0.3,
        sigma_near_rad=0.05,
        near_m=0.06,
        # the keyframes the cost moves through, the last one the kneel (MuJoCo MPC chains contact keyframes
        # for multi-phase motions): "hands_knees" is the kneel pitched forward by hands_knees_pitch_rad, hips
        # flexed as much more (thighs vertical) and arms pointing at the floor; "heel_sit" the kneel with knees
        # and hips flexed heel_sit_flex_rad more (sitting back on the heels, trunk upright); the cost moves on
        # once the trunk is within advance_height_m of a keyframe's height and advance_up_z of its up_z
        waypoints=["hands_knees", "heel_sit", "kneel"],
        # from this waypoint on ("" = never) the plans move in the getup env's sagittal action space
        # (training/envs/sagittal.py): pitch joints left = right, roll and yaw at home; a sampler over all 23
        # joints arrived sprawled (hip yaw ±0.8 rad, waist ±1 rad) and did not square it within its horizon
        sagittal_from="heel_sit",
        hands_knees_pitch_rad=1.2,
        heel_sit_flex_rad=0.5,
        advance_height_m=0.05,
        # the kneel's trunk height target is at least the gate's height (0.4 m) plus this: the kneel keyframe
        # rests 5 mm above the gate's floor, and a trunk that sways about it is below the gate half the time
        kneel_height_margin_m=0.01,
        advance_up_z=0.15,
        # the kneeling posture the gate must hold in: both knees at least this flexed and both hips no more
        # flexed than this (a forward leg of a half kneel has its hip near −1.5 rad)
        kneel_knee_min_rad=events.KNEEL_KNEE_MIN_RAD,
        kneel_hip_min_rad=events.KNEEL_HIP_MIN_RAD,
        weights=config_dict.create(
            trunk_height=400.0,  # (h − the keyframe's h)² [1/m²]: two-sided (one-sided overshot into a crouch)
            waist_height=100.0,  # (h_waist − the keyframe's)² [1/m²]
            upright=20.0,        # |u_z − the keyframe's u_z| of the trunk, on the way
            upright_kneel=200.0,  # the same at the kneel, where 1 − u_z ≈ tilt²/2 is flat near vertical
            pose=0.5,            # Σ (q − q_keyframe)² [1/rad²] over the arms, head and waist, on the way
            leg_pose=2.0,        # the same over the legs: the kneel is a leg posture
            pose_kneel=2.0,      # the two at the kneel: the double kneel rests upright; a sprawled one (hips
            leg_pose_kneel=20.0,  # rolled and yawed, leaning back on a foot) does not
            energy=0.002,        # Σ |τ·q̇| [1/W]
            root_velocity=0.05,  # ‖root twist‖² near the kneel [s²/m²]: balance rather than sway
            gate=5.0,            # paid per step while §4.8's gate holds (a negative cost)
            terminal=5.0,        # the horizon's last step counts this many times
        ),
        seed=0,
    )

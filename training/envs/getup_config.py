"""The getup tasks' configs: what the keyframe expert and the baseline share (getup_common_config) and the
keyframe expert's own (default_config). Why each setting is what it is: training/envs/getup.py's docstring."""
from __future__ import annotations

from ml_collections import config_dict

from common import observation as obsdef
from training.envs import base
from training.envs import getup_rewards as G
from training.envs.fallen import PREPARE_S

GETUP_ACTION_SCALE_RAD = 2.0    # rad per unit action (see getup_common_config)


def getup_common_config() -> config_dict.ConfigDict:
    """Settings the getup expert and the baseline share (starts, model, observation)."""
    cfg = base.base_config()
    cfg.collision = "full_body"
    # ±0.5 rad around home (the joystick's scale) cannot even reach the kneel keyframe (knee 1.9 rad vs
    # home 0.4): with it both stage-2 runs learned to lie flat with straight legs. 2 rad per unit puts the
    # kneel at |a| ≈ 0.75, off tanh saturation; base.py caps it per joint at the joint's range.
    cfg.action_scale = GETUP_ACTION_SCALE_RAD
    cfg.episode_length = 500
    cfg.obs_terms = [list(t) for t in obsdef.TERMS_GETUP]
    cfg.obs_noise_scale = 0.0            # U(−1, 1)·this per observation entry; 0 = off (seed's fine-tune: 1)
    cfg.start_probs = [0.4, 0.4, 0.2]    # (fallen, kneeling, standing) for the full task
    cfg.fallen_bank_size = 128           # distinct precomputed fallen starts
    cfg.fallen_seed = 0
    # fallen starts = the state after the runtime's PREPARE ramp of this length [s] (training/envs/fallen.py:
    # the loop hands the policy that robot, not the settled fall); 0 = the settled fall itself
    cfg.fallen_prepare_s = PREPARE_S
    cfg.standing_targets_m = [G.STANDING_TORSO_M, G.STANDING_WAIST_M]   # (torso, waist) after the gate
    # assist stage (training/envs/assists.py; ours, not the seed's): the elastic harness (stiffness 0 = none)
    cfg.harness = config_dict.create(stiffness_n_per_m=0.0, anchor_height_m=3.0, attach_above_trunk_m=0.3,
                                     slack_trunk_height_m=G.STANDING_TORSO_M)
    return cfg


def default_config() -> config_dict.ConfigDict:
    cfg = getup_common_config()
    cfg.stage = "full"
    # (fallen, kneeling, standing) of the curriculum's stages: the seed's stage 1 starts fallen, stage 2 at
    # the kneel. A kneeling share in stage 1 (ours, a reverse curriculum) shows PPO the kneel's reward early
    cfg.stage1_start_probs = [1.0, 0.0, 0.0]
    # stage 1's reward per step while §4.8's gate holds that step (getup_rewards.kneel_height_reward; ours,
    # 0 = the seed's stage 1)
    cfg.stage1_gate_reward = 0.0
    cfg.stage2_start_probs = [0.0, 1.0, 0.0]
    cfg.energy_weight = 0.0
    cfg.gate_latches = True                 # the full task's gate stays on once met (module docstring)
    cfg.stage2_fall_trunk_height_m = 0.35   # stage 2 ends when the trunk drops below this [m] (docstring)
    cfg.stage2_fall_up_z = 0.7              # ... or when the trunk's up_z falls below this (46° of tilt)
    # knockdown starts (training/envs/handover.py knockdown_bank; ours): this share of the fallen starts is
    # instead where the teacher hands `joystick_policy`, knocked over by a push, to the getup expert mid-fall
    # (from `bank_starts` standing starts, seeds from `seed`); 0 = the seed's fallen starts only. The shares of
    # these, rise_starts, collapse_starts and prone_starts sum to at most 1
    cfg.knockdown_starts = config_dict.create(prob=0.0, joystick_policy="", bank_starts=256, seed=200_000)
    # rise starts (rise_bank.py; ours, stage 1's reverse curriculum): this share of the fallen starts is instead
    # a state along the rises `getup_policy` makes with the harness (stiffness [N/m], slack [m]) from
    # `bank_starts` fallen starts (seeds from `seed`), at progress min_progress … 1 toward the kneel
    cfg.rise_starts = config_dict.create(prob=0.0, getup_policy="", harness_n_per_m=400.0, harness_slack_m=0.45,
                                         bank_starts=128, seed=600_000, min_progress=0.5)
    # collapse starts (kneel_collapse.py; ours, stage 1's reverse curriculum): this share of the fallen starts is
    # instead a state along the collapse from the kneel (PD gains × gain_scale, a tipping push of push_rad_s
    # [rad/s] about an axis push_axis_deg [deg] from world x: (0, 180) tips it face down, duration_s [s]) of
    # `bank_starts` starts, at progress 0 … max_progress toward the floor
    cfg.collapse_starts = config_dict.create(prob=0.0, max_progress=1.0, bank_starts=256, seed=700_000,
                                             gain_scale=0.1, push_rad_s=2.0, duration_s=2.0,
                                             push_axis_deg=[0.0, 360.0])
    # prone starts (prone_path.py; ours, stage 1's reverse curriculum): this share of the fallen starts is instead
    # a settled state along kneel (0) → hands and knees (1, trunk pitched forward hands_knees_pitch_rad) → lying
    # face down (2), at progress U(min_progress, max_progress), joint targets ± target_noise_rad, held settle_s [s]
    cfg.prone_starts = config_dict.create(prob=0.0, min_progress=0.0, max_progress=2.0, bank_starts=256,
                                          seed=800_000, hands_knees_pitch_rad=1.4, target_noise_rad=0.1,
                                          settle_s=1.0)
    # stage 2's reverse curriculum (training/envs/start_path.py; ours, not the seed's). max_progress 0 = off:
    # every stage-2 episode starts at the kneel, as the seed's. Else a start is drawn at progress
    # U{min_progress … max_progress} along standing (0) → half kneel (1) → kneel (2), or at the kneel with
    # kneel_prob. min_progress > 0 spends the starts on the part still to learn (the swing, p 1 … 2).
    # left_leg_waypoints: (progress, left hip pitch, knee, ankle pitch [rad]); 1.0 is the half kneel, the rest
    # swing the leg back with the knee lifted (start_path.py's docstring)
    cfg.reverse_curriculum = config_dict.create(
        max_progress=0.0, min_progress=0.0, kneel_prob=0.25, bank_size=41,
        left_leg_waypoints=[[1.0, -1.5, 2.2, -0.7], [1.3, -1.4, 2.3, -0.87], [1.5, -1.2, 2.34, -0.87],
                            [1.6, -0.9, 2.34, -0.87], [1.68, -0.75, 2.34, -0.87], [1.75, -0.5, 2.3, -0.05]])
    return cfg

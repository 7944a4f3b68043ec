"""The getup tasks' configs: what the keyframe expert and the baseline share (getup_common_config) and the
keyframe expert's own (default_config). Why each setting is what it is: training/envs/getup.py's docstring."""
from __future__ import annotations

from ml_collections import config_dict

from common import observation as obsdef
from training.envs import base, starts
from training.envs import getup_rewards as G

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
    cfg.standing_targets_m = [G.STANDING_TORSO_M, G.STANDING_WAIST_M]   # (torso, waist) after the gate
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
    # stage 1's reward per step × exp(−up error / the gate's) at the gate's height: a slope to the gate's last
    # degrees (getup_rewards.upright_at_gate_height; ours, 0 = the seed's)
    cfg.stage1_upright_reward = 0.0
    # a stage-1 episode ends once its trunk, having reached the gate's height, drops this far below it [m]
    # (ours, 0 = the seed's: stage 1 never ends early)
    cfg.stage1_drop_below_m = 0.0
    # "sagittal": the policy sets the pitch joints, left and right alike, the rest hold home (envs/sagittal.py;
    # ours, FRASA's reduced getup; "full" = the seed's 23 joints)
    cfg.action_space = "full"
    cfg.stage2_start_probs = [0.0, 1.0, 0.0]
    cfg.energy_weight = 0.0
    cfg.gate_latches = True                 # the full task's gate stays on once met (module docstring)
    cfg.stage2_fall_trunk_height_m = 0.35   # stage 2 ends when the trunk drops below this [m] (docstring)
    cfg.stage2_fall_up_z = 0.7              # ... or when the trunk's up_z falls below this (46° of tilt)
    # the fallen starts and stage 2's reverse curriculum; a share of the fallen starts from the start banks
    # (ours), shares summing to at most 1, all off by default (training/envs/starts/)
    starts.add_config_groups(cfg, "getup")
    return cfg

"""A run's configs: the PPO presets (`ppo_config`) and the env's (`envs.default_config`), with `--config
key=value` applied (`build_configs`). A saved run's configs come back through training/ppo/migration.py."""
from __future__ import annotations

from typing import Sequence

from ml_collections import config_dict

from training import envs
from training.core.overrides import TOY_ENV_OVERRIDES, apply_overrides
from training.distill import finetune as student_finetune
from training.imitation import config as imitation

PRESETS = ("gpu", "cpu", "toy")


def ppo_config(task: str, preset: str = "gpu") -> config_dict.ConfigDict:
    """Per-task PPO config. `gpu`: Playground's T1 joystick recipe (locomotion_params.py, T1Joystick*),
    the seed's getup runs on the same settings; `cpu`: the same recipe sized for the CPU backend
    (a few thousand env-steps/s); `toy`: tiny networks and batches for CPU smoke tests."""
    if preset not in PRESETS:
        raise ValueError(f"preset: {preset!r} is not one of {PRESETS}")
    cfg = config_dict.create(
        num_timesteps=200_000_000 if task == "joystick" else 100_000_000,
        num_envs=8192, batch_size=256, num_minibatches=32, unroll_length=20, num_updates_per_batch=4,
        discounting=0.97, learning_rate=3e-4, entropy_cost=0.005, clipping_epsilon=0.2, max_grad_norm=1.0,
        reward_scaling=1.0, normalize_observations=True, num_resets_per_eval=1,
        # getup episodes must restart from freshly sampled fallen/kneeling/standing states
        full_reset=task != "joystick",
        domain_randomization=task == "joystick",  # Playground T1: friction, gains, masses (envs.domain_randomize)
        policy_hidden_layer_sizes=(512, 256, 128), value_hidden_layer_sizes=(512, 256, 128),
        policy_obs_key="state", value_obs_key="privileged_state",
        # exploration: the sampling std × this (1 = brax's tanh-normal, std ≈ 0.69 at init). The same
        # pre-tanh noise moves a getup target 4× as far as a joystick one (action scale 2 vs 0.5 rad)
        policy_std_scale=1.0,
        # steps at the start of a run in which only the critic learns (the policy gets no gradient): a
        # fine-tune on new starts first fits the value of states the pretrained critic never saw, so the
        # first policy updates do not follow its errors (the full getup task from stage 2's policy)
        value_warmup_steps=0,
        # "normal" = a Gaussian around the mean the policy acts with (no tanh), std starting at init_noise_std
        # [action units]: the student's fine-tune (core/networks.py)
        policy_distribution="tanh_normal", init_noise_std=0.1,
        teacher=student_finetune.teacher_config(),   # the fine-tune's BC term (its extension's own group)
        imitation=imitation.finetune_config(),       # RL from the imitation policy: its BC term's data
        # one epoch ≈ 1 min on an H100 (joystick ~100k env-steps/s; the full-body getup 40–76k: half as many)
        checkpoint_every_steps=10_000_000 if task == "joystick" else 5_000_000,
        run_evals=True, num_eval_envs=128, deterministic_eval=True,
        log_training_metrics=True, training_metrics_steps=1_000_000,
    )
    if preset == "cpu":
        cfg.update(dict(
            # 256 envs: one host call steps them all on every core; more envs only lengthen the call
            # (the physics is ~linear in envs) while fewer updates per env step waste samples.
            num_envs=256,
            # 256 · 4 · 20 = 20 480 env steps per update (GPU: 163 840): 8× more updates per env step,
            # the sample-efficient end at this throughput; minibatches of 256 · 20 = 5 120 samples.
            batch_size=256, num_minibatches=4,
            # unroll, epochs, discount, lr, entropy, clipping: Playground's values (tuned for this task)
            # Networks as the GPU preset: a CPU run can be resumed on the GPU and vice versa, and the
            # runtime's MLP benchmark stays representative. Smaller nets would shave only the learner
            # share (~30 % of a step here).
            checkpoint_every_steps=1_000_000,   # one epoch ≈ 4–6 min at ~3–5 k env-steps/s
            num_eval_envs=64, training_metrics_steps=200_000))
    elif preset == "toy":
        cfg.update(dict(
            num_timesteps=2_000, num_envs=8, batch_size=8, num_minibatches=2, unroll_length=5,
            num_updates_per_batch=1, policy_hidden_layer_sizes=(16, 16), value_hidden_layer_sizes=(16, 16),
            checkpoint_every_steps=80, num_eval_envs=4, training_metrics_steps=80,
            # each of these compiles the MJX step once more: minutes on a CPU
            run_evals=False, domain_randomization=False, num_resets_per_eval=0))
    return cfg


def build_configs(task: str, preset: str, overrides: Sequence[str]):
    """(ppo config, env config) with --config key=value applied."""
    if task not in envs.TASKS:
        raise ValueError(f"task: {task!r} is not one of {envs.TASKS}")
    ppo_cfg, env_cfg = ppo_config(task, preset), envs.default_config(task)
    if preset == "toy":
        env_cfg.update({k: v for k, v in TOY_ENV_OVERRIDES.items() if k in env_cfg})
    apply_overrides({"ppo": ppo_cfg, "env": env_cfg}, overrides)
    return ppo_cfg, env_cfg

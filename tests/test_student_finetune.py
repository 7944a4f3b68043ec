"""The student's RL fine-tune (training/distill/finetune.py): the DAgger weights become a PPO policy that acts
exactly as the student did, the export is the student's artifact again, the BC term decays as configured and
reaches brax's PPO loss only while it is open, and the unified env's "skills" reward pays each expert's own
reward on its side of the switch."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from ml_collections import config_dict

from common import observation as obsdef
from training.core import networks as ppo_networks
from training.distill import finetune as F
from training.ppo.configs import ppo_config

OBS = {"state": (82,), "privileged_state": (125,), "waist_height": (1,)}
HIDDEN = (16, 8)


def _student(seed=0):
    """A brax bc (DAgger) policy and normaliser of the student's shape."""
    from brax.training.acme import running_statistics
    from brax.training.agents.bc import networks as bc_networks
    nets = bc_networks.make_bc_networks(OBS, obsdef.NUM_JOINTS, policy_hidden_layer_sizes=HIDDEN,
                                        policy_obs_key="state")
    policy = nets.policy_network.init(jax.random.PRNGKey(seed))
    normalizer = running_statistics.init_state(jax.tree.map(lambda s: jnp.zeros(s), OBS))
    return nets, normalizer, policy


def _ppo_cfg(**teacher):
    cfg = ppo_config("unified", "toy")
    cfg.update(dict(policy_distribution=F.NORMAL, init_noise_std=0.05, policy_hidden_layer_sizes=HIDDEN))
    cfg.teacher.update({"getup": "g", "joystick": "j", "bc_weight": 1.0, "bc_decay_steps": 1000, **teacher})
    return cfg


def test_the_fine_tuned_policy_starts_as_the_student_and_exports_back_to_it():
    bc_nets, normalizer, policy = _student()
    assert F.is_student_checkpoint([normalizer, policy])
    params = F.init_params([normalizer, policy], _ppo_cfg())
    assert params[2] is None                                          # the critic starts fresh
    nets = ppo_networks.network_factory(_ppo_cfg())(OBS, obsdef.NUM_JOINTS)
    obs = {k: jax.random.normal(jax.random.PRNGKey(1), (4, *s)) for k, s in OBS.items()}
    logits = nets.policy_network.apply(normalizer, params[1], obs)
    mean = nets.parametric_action_distribution.mode(logits)
    loc = bc_nets.policy_network.apply(normalizer, policy, obs)[..., :obsdef.NUM_JOINTS]
    np.testing.assert_allclose(mean, loc, rtol=1e-5, atol=1e-6)      # acts with the student's loc
    np.testing.assert_allclose(logits[1], 0.05, rtol=1e-5)           # and samples with init_noise_std
    from training.export.brax import student_layers
    exported = student_layers(params[1])["params"]
    assert sorted(exported) == ["hidden_0", "hidden_1", "hidden_2"]
    np.testing.assert_array_equal(exported["hidden_2"]["kernel"], policy["params"]["hidden_2"]["kernel"][:, :23])


def test_a_student_checkpoint_needs_a_teacher_and_a_sampling_std():
    _, normalizer, policy = _student()
    cfg = _ppo_cfg()
    cfg.init_noise_std = 0.0
    with pytest.raises(ValueError, match="init_noise_std must be > 0"):
        F.init_params([normalizer, policy], cfg)
    cfg.update(dict(policy_distribution="tanh_normal", init_noise_std=0.05))   # it would act with tanh(loc)
    with pytest.raises(ValueError, match="fine-tunes under ppo.policy_distribution='normal'"):
        F.init_params([normalizer, policy], cfg)
    with pytest.raises(ValueError, match="teacher"):
        F.init_params([normalizer, policy], _ppo_cfg(bc_weight=0.0))
    ppo_params = [normalizer, policy, {"params": {}}]               # a PPO checkpoint passes unchanged
    assert F.init_params(ppo_params, cfg) is ppo_params


def test_the_trainer_gets_the_fine_tune_only_where_asked():
    """ppo/train.py knows one PPOExtension: plain PPO unless the config or the checkpoint asks for the fine-tune."""
    from training.core.extension import PPOExtension
    _, normalizer, policy = _student()
    plain = ppo_config("unified", "toy")
    assert type(F.extension(plain)) is PPOExtension and F.extension(plain).state_fields(None) == {}
    finetune = F.extension(_ppo_cfg(), [normalizer, policy])
    assert isinstance(finetune, F.StudentFinetune) and finetune.state_fields(None) == {"bc_count_start": 0.0}
    with pytest.raises(ValueError, match="teacher"):           # a DAgger checkpoint under plain PPO
        F.extension(plain, [normalizer, policy]).initial_params([normalizer, policy])


def test_the_bc_weight_decays_linearly_to_zero_and_counts_samples():
    assert float(F.bc_weight(0.0, 2.0, 1000)) == 2.0
    assert float(F.bc_weight(250.0, 2.0, 1000)) == pytest.approx(1.5)
    assert float(F.bc_weight(5000.0, 2.0, 1000)) == 0.0
    assert float(F.bc_weight(5000.0, 2.0, 0)) == 2.0                  # no decay
    from brax.training import types
    state = config_dict.ConfigDict({"count": types.UInt64(hi=1, lo=5)})
    assert float(F.sample_count(state)) == pytest.approx(2.0 ** 32 + 5, rel=1e-6)


def test_the_teacher_term_is_in_the_ppo_loss_only_while_open(monkeypatch):
    from brax.training.agents.ppo import losses as ppo_losses

    from training.distill import teacher as teacher_module
    original = ppo_losses.compute_ppo_loss
    monkeypatch.setattr(teacher_module, "load_expert", lambda path, kind: kind)

    def fake_teacher(*_args, **kwargs):
        return lambda obs: (None, {"loc": jnp.zeros(obs["state"].shape[:-1] + (obsdef.NUM_JOINTS,))})
    monkeypatch.setattr(teacher_module, "make_teacher", fake_teacher)

    class Env:
        obs_terms = obsdef.TERMS_UNION

        @staticmethod
        def manifest_fields():
            return {"action_scale": 2.0}
    with F.teacher_term(_ppo_cfg(), Env(), count_start=0.0):
        assert ppo_losses.compute_ppo_loss is not original
    assert ppo_losses.compute_ppo_loss is original
    with F.teacher_term(_ppo_cfg(bc_weight=0.0), Env(), count_start=0.0):
        assert ppo_losses.compute_ppo_loss is original


def test_the_bc_error_compares_the_executed_actions():
    """The label is the teacher's action: a "normal" policy executes its mode (compared through tanh, as brax bc's
    loss), a tanh-normal one executes its mode tanh(μ) itself."""
    label = jnp.array([[0.3, -0.9, 0.5]])
    assert float(F.bc_error(label, label, squashed=True)[0]) == pytest.approx(0.0, abs=1e-12)
    assert float(F.bc_error(label, label, squashed=False)[0]) == pytest.approx(0.0, abs=1e-12)
    off = F.bc_error(label + 0.1, label, squashed=True)
    assert float(off[0]) == pytest.approx(3 * 0.01, rel=1e-5)


def test_the_teacher_is_the_stitched_one_or_the_keyframe_chain():
    from training.distill.teacher import KeyframeStageObservation, WaistObservation, teacher_observation
    chain = _ppo_cfg(getup="", joystick="", roll="r", rise="s", stand="t")
    assert F.teacher_roles(chain) == {"roll": "r", "rise": "s", "stand": "t"}
    assert teacher_observation(F.teacher_roles(chain)).func is KeyframeStageObservation
    assert teacher_observation(F.teacher_roles(_ppo_cfg())) is WaistObservation
    with pytest.raises(ValueError, match="a teacher is getup"):        # roles of both kinds at once
        teacher_observation(F.teacher_roles(_ppo_cfg(roll="r")))


def test_the_chains_hand_over_to_the_stand_is_the_gate_unless_configured(monkeypatch):
    from common import events
    seen = []
    monkeypatch.setattr(F, "teacher_observation", lambda roles, up_error: seen.append(up_error) or (lambda e, b: e))
    for extra in ({}, {"handover_up_error": 0.05}):
        cfg = _ppo_cfg(getup="", joystick="", roll="r", rise="s", stand="t", **extra)
        F.StudentFinetune(cfg).wrap_env_fn(None, full_reset=False)
    assert seen == [events.KNEEL_GATE_UP_ERROR, 0.05]


@pytest.fixture(scope="module")
def skills_env():
    from training import envs
    return envs.make("unified", config_overrides={"reward.mode": "skills", "fallen.bank_starts": 2,
                                                  "reward.course.progress_weight": 10.0})


def _info_at(env, keyframe):
    from common import model as t1model
    from training.envs import getup_rewards as G
    from training.envs.joystick import Joystick
    data = env.make_data(jnp.asarray(t1model.keyframe_qpos(env.mj_model, keyframe)), jnp.zeros(env.mj_model.nv))
    info = {**env.body_readings(data), **Joystick.initial_feet_info(), "command": jnp.zeros(3),
            "last_act": jnp.zeros(obsdef.NUM_JOINTS), "phase": obsdef.initial_gait_phase(jnp),
            "course": jnp.zeros((), bool), "course_best_x": data.qpos[0], "course_credit_x": data.qpos[0]}
    info["rise_track"] = G.rise_track_start(info["trunk_height"])
    return data, info


def test_the_skills_reward_pays_each_expert_its_own_on_its_side_of_the_switch(skills_env):
    from training.envs import getup_rewards as G
    env, cfg = skills_env, skills_env._config.reward
    bonus = cfg.getup.scale * G.gated_reward_max()
    data, info = _info_at(env, "home")                     # standing: the joystick's terms + the bonus
    reward, terms = env._skills_reward(data, jnp.zeros(obsdef.NUM_JOINTS), info)
    assert float(terms["standing"]) == 1.0 and float(terms["reward/getup"]) == 0.0
    assert float(terms["reward/joystick"]) > bonus and float(reward) == pytest.approx(
        float(terms["reward/joystick"]) * env.dt, rel=1e-5)
    data, info = _info_at(env, "kneel")                    # the kneel keyframe: the getup expert's, gate on
    reward, terms = env._skills_reward(data, jnp.zeros(obsdef.NUM_JOINTS), info)
    assert float(terms["standing"]) == 0.0 and float(terms["gate"]) == 1.0
    height, pose = env.gated_rewards(data.qpos[7:], info, jnp.ones((), bool))
    assert float(terms["reward/getup"]) == pytest.approx(cfg.getup.scale * float(height + pose), rel=1e-4)
    assert 0.0 < float(terms["reward/getup"]) < bonus       # the switch is no wall to stay below
    with pytest.raises(ValueError, match="reward.mode 'walk'"):
        from training import envs
        envs.make("unified", config_overrides={"reward.mode": "walk", "fallen.bank_starts": 2})


def test_wall_course_samples_keep_the_full_bc_weight_where_held(skills_env):
    """bc_hold_in_course: samples whose episode's "wall_course" metric is on keep bc_weight; others decay."""
    data, info = _info_at(skills_env, "home")
    assert float(skills_env._skills_reward(data, jnp.zeros(obsdef.NUM_JOINTS), info)[1]["wall_course"]) == 0.0
    info["course"] = jnp.ones((), bool)
    assert float(skills_env._skills_reward(data, jnp.zeros(obsdef.NUM_JOINTS), info)[1]["wall_course"]) == 1.0
    from brax.training import types
    summed = jnp.array([[0.0, 3.0], [1.0, 0.0]])            # episode_metrics: the metric summed so far
    batch = types.Transition(observation=None, action=None, reward=None, discount=None, next_observation=None,
                             extras={"state_extras": {"episode_metrics": {"wall_course": summed}}})
    in_course = F.in_wall_course(batch)
    np.testing.assert_array_equal(in_course, [[False, True], [True, False]])
    np.testing.assert_allclose(F.sample_weights(jnp.float32(0.25), in_course, 1.0), [[0.25, 1.0], [1.0, 0.25]])
    np.testing.assert_allclose(F.sample_weights(jnp.float32(0.25), False, 1.0), 0.25)


def test_wall_course_episodes_are_paid_for_credited_progress_only(skills_env):
    """reward.course.progress_weight × the metres credited (wall_course.credited_progress), in courses only."""
    env, cfg = skills_env, skills_env._config.reward
    data, info = _info_at(env, "home")
    info.update(command=jnp.array([0.4, 0.0, 0.0]), course_credit_x=data.qpos[0] - 0.5)   # 0.5 m banked
    walk, terms = env._skills_reward(data, jnp.zeros(obsdef.NUM_JOINTS), dict(info))
    assert float(terms["course_progress_m"]) == 0.0                                     # not a course episode
    info["course"] = jnp.ones((), bool)
    reward, terms = env._skills_reward(data, jnp.zeros(obsdef.NUM_JOINTS), info)
    assert float(terms["course_progress_m"]) == pytest.approx(0.4 * env.dt, rel=1e-4)
    assert float(reward - walk) == pytest.approx(cfg.course.progress_weight * 0.4 * env.dt, rel=1e-3)
    info["course_credit_x"] = data.qpos[0]                                                # nothing banked: standing
    assert float(env._skills_reward(data, jnp.zeros(obsdef.NUM_JOINTS), info)[1]["course_progress_m"]) == 0.0


def test_with_walk_after_stand_up_the_walk_pays_only_once_a_getup_has_stood_up(skills_env, monkeypatch):
    """reward.walk_after_stand_up: above the switch, a getup still down (events.py: not yet standing for
    STAND_HOLD_S) is paid the getup expert's reward; the hold's last tick hands over to the walk."""
    env = skills_env
    monkeypatch.setattr(env, "_walk_after_stand_up", True)
    data, info = _info_at(env, "home")
    info["rise_track"] = {**info["rise_track"], "down": jnp.ones((), bool)}   # risen, the hold just begun
    for _ in range(env._stand_hold_ticks - 1):
        _, terms = env._skills_reward(data, jnp.zeros(obsdef.NUM_JOINTS), info)
        assert float(terms["standing"]) == 0.0 and float(terms["reward/joystick"]) == 0.0
        assert float(terms["reward/getup"]) > 0.0
    _, terms = env._skills_reward(data, jnp.zeros(obsdef.NUM_JOINTS), info)
    assert float(terms["standing"]) == 1.0 and float(terms["reward/getup"]) == 0.0
    data, info = _info_at(env, "home")                      # never down (a walk): the walk pays at once
    assert float(env._skills_reward(data, jnp.zeros(obsdef.NUM_JOINTS), info)[1]["standing"]) == 1.0

"""The seed's getup rewards (thesis §4.7–4.8, training/envs/getup_rewards.py) against hand computations,
and each getup task's reward terms on fixed states. Few env jits here (CPU backend): fast."""
from __future__ import annotations

import math
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from training import envs
from training.envs import getup_rewards as G

UP = np.array([0.0, 0.0, 1.0])


def _tilted(deg):
    """Unit up vector tilted by deg about x."""
    a = math.radians(deg)
    return np.array([0.0, -math.sin(a), math.cos(a)])


@pytest.mark.parametrize("h, h_des, r", [
    (0.0, 0.4, 0.0), (0.1, 0.4, 0.25), (0.3, 0.4, 0.75), (0.4, 0.4, 1.0), (0.9, 0.4, 1.0), (-0.2, 0.4, 0.0)])
def test_part_height_reward(h, h_des, r):
    # r = 1 − clip((h_des − min(h, h_des)) / h_des, 0, 1)
    assert float(G.part_height_reward(h, h_des)) == pytest.approx(r, abs=1e-7)


@pytest.mark.parametrize("up_z, r", [(1.0, 0.5625), (0.0, 0.25), (-1.0, 0.0625), (0.5, 0.390625)])
def test_orientation_reward(up_z, r):
    assert float(G.orientation_reward(up_z)) == pytest.approx(r, abs=1e-7)    # (0.25·u_z + 0.5)²


def test_height_orientation_reward_by_hand():
    # torso 0.3 of 0.67, waist at 0.55 of 0.55, upright: 2·0.5625·(0.3/0.67 + 1 + 1)/3
    expected = 2 * 0.5625 * (0.3 / 0.67 + 1.0 + 1.0) / 3
    assert float(G.height_orientation_reward(0.3, 0.6, 1.0, 0.67, 0.55)) == pytest.approx(expected, rel=1e-6)
    # lying upside down on the floor: 2·0.0625·(0 + 0 + 1)/3
    assert float(G.height_orientation_reward(0.0, 0.0, -1.0, 0.67, 0.55)) == pytest.approx(0.125 / 3, rel=1e-6)


def test_pose_reward():
    q_ref = np.linspace(-1, 1, 23)
    q = q_ref + 0.1 * np.arange(23) / 23
    expected = math.exp(-0.5 * float(np.sum((q - q_ref) ** 2)))
    assert float(G.pose_reward(jnp.asarray(q), jnp.asarray(q_ref))) == pytest.approx(expected, rel=1e-5)
    assert float(G.pose_reward(jnp.asarray(q_ref), jnp.asarray(q_ref))) == pytest.approx(1.0)


def test_energy_cost():
    dq = np.array([1.0, -2.0, 0.5] + [0.0] * 20)
    tau = np.array([3.0, 4.0, -10.0] + [1.0] * 20)
    tau_max = np.array([7.0, 7.0, 18.0] + [30.0] * 20)
    expected = 3.0 / 7.0 + 8.0 / 7.0 + 5.0 / 18.0
    cost = float(G.energy_cost(jnp.asarray(dq), jnp.asarray(tau), jnp.asarray(tau_max)))
    assert cost == pytest.approx(expected, rel=1e-6)


@pytest.mark.parametrize("h, up, ok", [
    (0.405, UP, True), (0.3951, UP, True), (0.3949, UP, False),     # 0.4 − min(h, 0.4) < 0.005
    (0.67, UP, True), (0.9, UP, True),                              # stays on while rising (min)
    (0.67, _tilted(0.5), True), (0.67, _tilted(0.6), False),         # ‖u − e_z‖ < 0.01: tilt < 0.573°
    (0.1, UP, False)])
def test_gate_exactly_as_written(h, up, ok):
    assert bool(G.gate(jnp.float32(h), jnp.float32(up[2]))) is ok


def test_gate_is_the_evaluations_kneel_gate():
    """One definition (common/events.kneel_gate): the reward's float32 jax reading agrees with the evaluations'
    float64 numpy one, here and around both edges."""
    from common.events import kneel_gate_mask
    for h in (0.3, 0.3949, 0.3951, 0.67):
        for deg in (0.0, 0.5, 0.56, 0.59, 0.6, 10.0):
            up_z = _tilted(deg)[2]
            assert bool(G.gate(jnp.float32(h), jnp.float32(up_z))) == bool(kneel_gate_mask(h, up_z)), (h, deg)


def test_gated_terms_by_hand():
    on, off = jnp.asarray(True), jnp.asarray(False)
    assert float(G.gated_height_reward(off, 0.7, 0.9)) == pytest.approx(0.7)
    assert float(G.gated_height_reward(on, 0.7, 0.9)) == pytest.approx(1.83 + 0.9)
    assert float(G.gated_pose_reward(off, 0.4, 0.5)) == pytest.approx(0.4)
    assert float(G.gated_pose_reward(on, 0.4, 0.5)) == pytest.approx(0.6 + 100 * 0.5)


def test_the_latched_gate_holds_until_the_trunk_is_down():
    on, off = jnp.asarray(True), jnp.asarray(False)
    assert bool(G.latched_gate(on, off, 0.4)) and bool(G.latched_gate(off, on, 0.36))       # met, then held
    assert not bool(G.latched_gate(off, on, 0.34)) and not bool(G.latched_gate(off, off, 0.6))   # down; never met


# ------------------------------------------------------------------ the tasks' terms
SMALL = {"fallen.bank_starts": 2, "episode_length": 20}


@pytest.fixture(scope="module")
def full_env():
    return envs.make("getup", config_overrides=SMALL)


@pytest.fixture(scope="module")
def kneel_env():
    return envs.make("getup_kneel", config_overrides=SMALL)


@pytest.fixture(scope="module")
def stand_env():
    return envs.make("getup_stand", config_overrides=SMALL)


def _fake_data(qpos, qvel, tau):
    return SimpleNamespace(qpos=jnp.asarray(qpos), qvel=jnp.asarray(qvel), actuator_force=jnp.asarray(tau))


def _state(env, dq_joint=0.3, tau=2.0):
    qpos = np.asarray(env._kneel_qpos).copy()
    qpos[7:] += 0.05
    qvel = np.zeros(29)
    qvel[6:] = dq_joint
    return _fake_data(qpos, qvel, np.full(23, tau))


def _info(h, up, waist=0.29, **extra):
    return {"trunk_height": jnp.float32(h), "waist_height": jnp.float32(waist), "up": jnp.asarray(up, jnp.float32),
            "up_z": jnp.float32(up[2]), **extra}


def test_kneel_targets_come_from_the_keyframe(full_env):
    torso, waist = (float(v) for v in full_env._kneel_targets)
    assert torso == pytest.approx(float(full_env._kneel_qpos[2]), abs=1e-6)    # the root is the Trunk
    assert 0.2 < waist < torso
    np.testing.assert_allclose(np.asarray(full_env._standing_targets), [0.67, 0.55])


@pytest.mark.parametrize("gate_on", [False, True])
def test_full_task_terms_by_hand(full_env, gate_on):
    torso_k, waist_k = (float(v) for v in full_env._kneel_targets)
    h_torso, h_waist = 0.41, 0.3
    up = UP if gate_on else _tilted(5.0)
    info = _info(h_torso, up, h_waist)
    info["gate"] = full_env._gate_state(G.gate(info["trunk_height"], info["up_z"]), jnp.asarray(False), info)
    terms = full_env._reward_terms(_state(full_env), info)
    r_ori = (0.25 * up[2] + 0.5) ** 2
    ho = lambda t, w: 2 * r_ori * (min(h_torso, t) / t + min(h_waist, w) / w + 1) / 3  # noqa: E731
    q = np.asarray(full_env._kneel_qpos[7:]) + 0.05
    pose_kneel = math.exp(-0.5 * 23 * 0.05 ** 2)
    pose_stand = math.exp(-0.5 * float(np.sum((q - np.asarray(full_env._default_pose)) ** 2)))
    assert bool(info["gate"]) is gate_on and set(terms) == set(full_env.config.reward.scales)
    if gate_on:
        assert float(terms["height"]) == pytest.approx(1.83 + ho(0.67, 0.55), rel=1e-5)
        assert float(terms["pose"]) == pytest.approx(0.6 + 100 * pose_stand, rel=1e-4)
    else:
        assert float(terms["height"]) == pytest.approx(ho(torso_k, waist_k), rel=1e-5)
        assert float(terms["pose"]) == pytest.approx(pose_kneel, rel=1e-5)
    limits = np.asarray(full_env._tau_limit)
    assert float(terms["energy"]) == pytest.approx(float(np.sum(0.3 * 2.0 / limits)), rel=1e-5)


def test_the_full_task_s_gate_is_per_step_and_the_kneel_s_latches(full_env, kneel_env):
    """The full task switches its rewards on §4.8's gate as written (a latched one was reward-hacked:
    LESSONS, `getup_full_from_baseline`); the kneel task carries the kneel reached and not lost since."""
    upright, tilted = _info(0.6, UP, 0.5), _info(0.6, _tilted(3.0), 0.5)
    down = _info(0.3, _tilted(3.0), 0.2)
    on, off = jnp.asarray(True), jnp.asarray(False)
    assert not bool(full_env._gate_state(off, on, tilted)) and bool(full_env._gate_state(on, off, upright))
    assert float(full_env._reward_terms(_state(full_env), dict(tilted, gate=off))["height"]) < 1.83
    still = kneel_env._gate_state(off, on, tilted)
    assert bool(still) and not bool(kneel_env._gate_state(off, still, down))


def test_the_kneel_task_carries_its_latched_gate_through_steps():
    # the CPU backend: the gate's carry is the env's own code on either physics, and MJX's compile takes minutes
    env = envs.make("getup_kneel", config_overrides={**SMALL, "backend": "cpu"})
    state = jax.jit(env.reset)(jax.random.PRNGKey(3))
    step = jax.jit(env.step)
    for _ in range(3):
        state = step(state, jnp.zeros(23))
    expected = G.gate(state.info["trunk_height"], state.info["up_z"])
    assert state.info["gate"].dtype == jnp.bool_
    assert float(state.metrics["gate"]) == float(state.info["gate"]) == float(state.metrics["success"])
    assert bool(state.info["gate"]) >= bool(expected)


def test_gate_reached_counts_the_first_step_the_gate_holds():
    """The kneel's success: an episode's sum of gate_reached is 1 when §4.8's gate held at any step since the reset."""
    env = envs.make("getup_stand", config_overrides={"episode_length": 20, "backend": "cpu"})
    state = jax.jit(env.reset)(jax.random.PRNGKey(0))     # at the kneel keyframe, the gate's pose
    step = jax.jit(env.step)
    scale = jnp.asarray(env.manifest_fields()["action_scale"])
    hold = jnp.asarray((env._kneel_qpos[7:] - env._default_pose) / scale, jnp.float32)
    reached, held = [], []
    for _ in range(6):
        state = step(state, hold)
        reached.append(float(state.metrics["gate_reached"]))
        held.append(bool(G.gate(state.info["trunk_height"], state.info["up_z"])))
    assert any(held), "the kneel keyframe held by its own targets meets the gate at first"
    first = held.index(True)
    assert reached == [1.0 if i == first else 0.0 for i in range(6)], (reached, held)


def test_the_stages_rewards(kneel_env, stand_env):
    info = _info(0.2, _tilted(90.0), 0.15, gate=jnp.asarray(False))
    t1, t2 = kneel_env._reward_terms(_state(kneel_env), info), stand_env._reward_terms(_state(stand_env), info)
    assert float(t1["height"]) < 1.0                     # stage 1: the keyframe reward only
    assert float(t1["pose"]) == pytest.approx(math.exp(-0.5 * 23 * 0.05 ** 2), rel=1e-5)
    # stage 2: §4.7's rewards toward standing, no gate bonuses: HO(torso 0.67, waist 0.55) and pose(q, q_init)
    r_height = (0.2 / 0.67) + (0.15 / 0.55)
    assert float(t2["height"]) == pytest.approx(2.0 * 0.25 * (r_height + 1.0) / 3.0, rel=1e-5)
    assert float(t2["pose"]) == pytest.approx(float(G.pose_reward(_state(stand_env).qpos[7:],
                                                                  stand_env._default_pose)), rel=1e-5)
    assert set(t1) == {"height", "pose", "gate", "upright", "energy"}
    assert set(t2) == {"height", "pose", "energy"}


def test_the_kneel_s_gate_term_pays_only_while_the_gate_holds_this_step(kneel_env):
    """reward.scales.gate (ours; 0 = the seed): the term is 1 on a step that meets §4.8's gate (trunk above
    0.395 m, within 0.573° of vertical), whatever the latched gate says."""
    for tilt_deg, h, meets in ((0.3, 0.40, True), (1.25, 0.40, False), (0.3, 0.39, False)):
        terms = kneel_env._reward_terms(_state(kneel_env), _info(h, _tilted(tilt_deg), gate=jnp.asarray(True)))
        assert float(terms["gate"]) == (1.0 if meets else 0.0), (tilt_deg, h)


def test_the_kneel_s_upright_term_slopes_to_the_gate_at_its_height(kneel_env):
    """reward.scales.upright (ours; 0 = the seed): exp(−up error / 0.01) while the trunk is at the gate's height:
    1 upright, e⁻¹ at the gate's edge, falling with the tilt, nothing below the gate's height."""
    upright = [float(kneel_env._reward_terms(_state(kneel_env), _info(h, _tilted(deg), gate=jnp.asarray(False)))
                     ["upright"]) for deg, h in ((0.0, 0.40), (0.573, 0.40), (2.0, 0.40), (0.0, 0.39))]
    assert upright[0] == pytest.approx(1.0, rel=1e-4) and upright[1] == pytest.approx(1.0 / np.e, rel=1e-2)
    assert 0.0 < upright[2] < 0.05 and upright[3] == 0.0


def test_the_full_task_pays_the_seed_s_gated_terms_and_the_energy_cost(full_env):
    """The full task's reward terms: §4.8's gated height and pose, and §4.7's energy cost (the kneel's upright
    slope is the kneel task's only)."""
    assert set(full_env.config.reward.scales) == {"height", "pose", "energy"}
    assert set(full_env._reward_terms(_state(full_env), _info(0.65, _tilted(1.0), gate=jnp.asarray(False)))) == \
        {"height", "pose", "energy"}


def test_start_probabilities_per_task(full_env, kneel_env, stand_env):
    assert full_env.start_probabilities() == pytest.approx([0.4, 0.4, 0.2])
    assert stand_env.start_probabilities() == [0.0, 1.0, 0.0]
    assert kneel_env.start_probabilities() == [1.0, 0.0, 0.0]                      # the seed's stage 1
    kneeling_share = envs.make("getup_kneel", config_overrides={**SMALL, "start_probs": [0.7, 0.3, 0.0]})
    assert kneeling_share.start_probabilities() == pytest.approx([0.7, 0.3, 0.0])
    assert envs.make("getup_baseline", config_overrides=SMALL).start_probabilities() == [1.0, 0, 0]
    with pytest.raises(ValueError, match="start_probs"):
        envs.make("getup", config_overrides={**SMALL, "start_probs": [0.5, 0.5, 0.5]})


def test_robustness_noise_is_unit_uniform_on_every_entry():
    env = envs.make("getup", config_overrides={**SMALL, "obs_noise_scale": 1.0})
    assert np.all(np.asarray(env._noise_scale) == 1.0)
    assert all(envs.default_config(t).obs_noise_scale == 0.0 for t in ("getup", "getup_kneel", "getup_stand"))


def test_getup_actions_reach_the_kneel_keyframe_within_each_joint_range(stand_env):
    """±0.5 rad around home cannot reach the kneel (knee 1.9 vs 0.4 rad): the getup tasks use 2 rad per unit,
    capped per joint at the joint's range (what the runtime accepts), the kneel well inside tanh's ±1."""
    scale = np.asarray(stand_env.manifest_fields()["action_scale"])
    ranges = np.asarray(stand_env._q_max - stand_env._q_min)
    assert scale.shape == (23,) and np.all(scale <= ranges + 1e-6) and scale.max() == pytest.approx(2.0)
    needed = (np.asarray(stand_env._kneel_qpos[7:]) - np.asarray(stand_env._default_pose)) / scale
    assert np.max(np.abs(needed)) < 0.8
    assert envs.make("joystick").manifest_fields()["action_scale"] == 0.5   # unchanged: one number


def test_only_the_stand_task_ends_when_the_trunk_falls_below_the_fall_height(full_env, kneel_env, stand_env):
    """Stage 2 starts kneeling (trunk 0.405 m, upright): dropping below 0.35 m or tilting past up_z 0.7 ends
    it, so lying or leaning back with straight legs cannot pay. Stage 1 and the full task never end so."""
    fall_m, up_z = stand_env.config.fall_trunk_height_m, stand_env.config.fall_up_z
    assert fall_m < stand_env._kneel_targets[0]          # the kneel start itself is not a fall
    cases = ((fall_m - 0.01, 1.0, True), (fall_m + 0.01, 1.0, False), (0.405, 1.0, False), (0.67, 1.0, False),
             (0.405, up_z - 0.02, True), (0.405, up_z + 0.02, False), (0.32, 0.72, True))   # v5's leaning back
    for h, u, ends in cases:
        info = {"trunk_height": jnp.float32(h), "up_z": jnp.float32(u)}
        assert bool(stand_env._terminated(info)) is ends, (h, u)
        assert not bool(kneel_env._terminated(info)) and not bool(full_env._terminated(info))


# ------------------------------------------------------------------ the failed-rise tracker
def _failed_rises(h, up_z, hold_ticks):
    """Failed attempts the tracker counts over a trunk height series (standing as events.py's)."""
    from common.events import STANDING_TRUNK_THRESHOLD_M, UPRIGHT_UP_Z

    def tick(track, x):
        return G.rise_track_step(track, x[0], (x[0] >= STANDING_TRUNK_THRESHOLD_M) & (x[1] >= UPRIGHT_UP_Z),
                                 hold_ticks)

    _, failed = jax.lax.scan(tick, G.rise_track_start(h[0]), (jnp.asarray(h[1:]), jnp.asarray(up_z[1:])))
    return int(np.sum(np.asarray(failed)))


@pytest.mark.parametrize("segments", [
    # fallen start: two rises to kneeling that collapse, then a stand-up (2 failed)
    [(0.15, 0.15, 0.5), (0.15, 0.45, 0.5), (0.45, 0.15, 0.5), (0.15, 0.45, 0.5), (0.45, 0.2, 0.5),
     (0.2, 0.66, 1.0), (0.66, 0.66, 1.5)],
    # a stand shorter than the hold that drops back is a failed attempt, then a fall after a held stand is none
    [(0.15, 0.15, 0.5), (0.15, 0.66, 0.7), (0.66, 0.66, 0.5), (0.66, 0.15, 0.5), (0.15, 0.66, 1.0),
     (0.66, 0.66, 1.5), (0.66, 0.15, 0.3), (0.15, 0.15, 0.5)],
    # standing start, a fall, a wobble below the attempt rise, one clean getup
    [(0.66, 0.66, 1.0), (0.66, 0.15, 0.4), (0.15, 0.25, 0.2), (0.25, 0.15, 0.2), (0.15, 0.66, 1.0),
     (0.66, 0.66, 1.5)],
])
def test_failed_rises_count_as_the_events_definition(segments):
    """The reward's tracker and common/events.py count the same failed attempts on scripted series."""
    from common.events import STAND_HOLD_S, getup_events
    dt = 0.02
    h = np.concatenate([np.linspace(a, b, int(round(s / dt)), endpoint=False) for a, b, s in segments])
    up_z, t = np.ones_like(h), np.arange(len(h)) * dt
    expected = sum(a.outcome == "failed" for a in getup_events(t, h, up_z).attempt_log)
    assert expected > 0 or segments[0][0] > 0.6
    assert _failed_rises(h, up_z, int(round(STAND_HOLD_S / dt))) == expected


def test_a_failed_rise_counts_once_in_the_metric():
    """One step of the CPU-backend getup task from a state whose tracker holds an attempt that peaked 1 m up:
    the trunk is far below peak − 0.15 m, so the attempt fails and the metric counts it."""
    env = envs.make("getup", config_overrides={**SMALL, "backend": "cpu"})
    assert "failed_rises" in env.metric_names()
    state = jax.jit(env.reset)(jax.random.PRNGKey(0))
    track = dict(state.info["rise_track"], down=jnp.asarray(True), rising=jnp.asarray(True),
                 high=jnp.asarray(1.0, jnp.float32))
    state = state.replace(info={**state.info, "rise_track": track})
    after = jax.jit(env.step)(state, jnp.zeros(23))
    assert float(after.metrics["failed_rises"]) == 1.0 and not bool(after.info["rise_track"]["rising"])

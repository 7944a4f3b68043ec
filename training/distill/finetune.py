"""RL fine-tuning of the distilled student (AHC, arXiv 2511.06371: distil, then fine-tune by RL on the student's
own outcomes): PPO on the unified env's "skills" reward (training/envs/unified.py) from the
DAgger weights, plus a behaviour-cloning term toward the stitched teacher's labels that decays, so the student
keeps both skills while PPO changes what the teacher does badly (the seam at the waist switch).

Policy. The student, distilled without tanh (the seed's Table 5.2, output rule `linear`: distill/dagger.py), acts
with its mean, so PPO samples around it with brax's "normal" distribution (ppo.policy_distribution "normal"), a
state-independent learned std (ppo.init_noise_std at the start, in action units: 2 rad per unit on most joints);
the DAgger net's hidden layers become the PPO policy's MLP and its last layer's loc half the mean layer. The
student's own observation normaliser comes along, and the critic starts fresh (ppo.value_warmup_steps:
ppo/train.py).
BC term, added to brax's PPO loss, on the action the policy executes at its mode:
    mean over the batch of w_i(n) · e_i                                            (e_i: bc_error)
    w_i(n) = teacher.bc_weight · max(0, 1 − n / teacher.bc_decay_steps)
with e_i = Σ_joints (tanh(mode) − tanh(label))² for the "normal" policy (its mode is μ: brax bc's own loss,
distill/dagger.py) and Σ_joints (mode − label)² for tanh-normal (its mode is tanh(μ), the executed action), the
label the teacher's action in the student's map (teacher.py) and n the env steps of this fine-tune, read from the
observation normaliser's sample count (one sample per env step; the only step counter brax hands its loss) minus
the count it started from (the run state's `bc_count_start`). With teacher.bc_hold_in_course, samples of
wall-course episodes keep teacher.bc_weight (no decay): there the teacher trips across the wall and gets up
beyond, the one way on for a blind policy, while PPO alone learns to balance in front of it (training/LESSONS.md). They
are told apart by the unified env's "wall_course" metric, which brax hands the loss summed over the episode so far.
The teacher reads what it switches on (the privileged waist height, or the keyframe chain's stage): the env is
wrapped in training/distill/teacher.py's teacher_observation.
The trainer reaches all this through one PPOExtension (core/extension.py): `extension(ppo_cfg, restored)`.
"""
from __future__ import annotations

import contextlib

import jax.numpy as jnp
import numpy as np
from brax.training.agents.ppo import losses as ppo_losses
from ml_collections import config_dict

from common import events
from common import observation as obsdef
from training.core.extension import PPOExtension
from training.distill.teacher import load_teacher, teacher_observation
from training.export.brax import NORMAL

# the keys that make a PPO stage this fine-tune: a toy run keeps them (recipes/runner.py), as it keeps the learner
LEARNER_KEYS = ("ppo.teacher.", "ppo.policy_distribution", "ppo.init_noise_std")


def teacher_config():
    """The PPO config's `teacher` group: the teacher's experts (getup + joystick: the stitched teacher; roll + rise +
    stand: the keyframe getup's chain, its rise handing over to the stand at handover_up_error, §4.8's gate's own
    bound by default; training/distill/teacher.py) and the decaying BC term toward its labels (bc_weight 0 = none;
    bc_hold_in_course: no decay in wall-course episodes)."""
    return config_dict.create(getup="", joystick="", roll="", rise="", stand="",
                              handover_up_error=events.KNEEL_GATE_UP_ERROR, bc_weight=0.0, bc_decay_steps=0,
                              bc_hold_in_course=False)


def teacher_roles(ppo_cfg) -> dict:
    """{role: expert path} of the config's teacher (the roles with a path)."""
    t = ppo_cfg.teacher
    return {role: str(t.get(role, "")) for role in ("getup", "joystick", "roll", "rise", "stand") if t.get(role, "")}


def is_student_checkpoint(params) -> bool:
    """A brax bc (DAgger) checkpoint: (normaliser, MLP policy with 2·23 outputs: loc, scale) and no critic."""
    if len(params) != 2:
        return False
    inner = params[1].get("params", {})
    last = inner.get(f"hidden_{len(inner) - 1}", {})
    return "kernel" in last and np.shape(last["kernel"])[-1] == 2 * obsdef.NUM_JOINTS


def policy_from_student(student_policy, init_noise_std: float) -> dict:
    """brax bc policy params → the "normal" PPO policy's (MLP_0 = hidden layers, Dense_0 = loc half of the
    last layer, std_logparam = log of init_noise_std on every joint)."""
    inner = student_policy["params"]
    n = len(inner)
    last = inner[f"hidden_{n - 1}"]
    return {"params": {
        "MLP_0": {f"hidden_{i}": dict(inner[f"hidden_{i}"]) for i in range(n - 1)},
        "Dense_0": {"kernel": np.asarray(last["kernel"])[:, :obsdef.NUM_JOINTS],
                    "bias": np.asarray(last["bias"])[:obsdef.NUM_JOINTS]},
        "std_logparam": {"log_value": np.full(obsdef.NUM_JOINTS, np.log(init_noise_std), np.float32)}}}


def init_params(restored, ppo_cfg):
    """A run's first params: a DAgger checkpoint becomes the "normal" PPO policy (module docstring) with no critic
    (None: brax initialises it); anything else is returned as it is."""
    if restored is None or not is_student_checkpoint(restored):
        return restored
    if not uses_teacher(ppo_cfg):
        raise ValueError("a DAgger student checkpoint fine-tunes only with its teacher (ppo.teacher.getup and "
                         ".joystick, or .roll, .rise and .stand; .bc_weight > 0): its observation normaliser also "
                         "reads what the teacher switches on")
    if ppo_cfg.policy_distribution != NORMAL:
        raise ValueError(f"a DAgger student acts with its mean (output rule linear): it fine-tunes under "
                         f"ppo.policy_distribution={NORMAL!r}, got {ppo_cfg.policy_distribution!r}")
    if not float(ppo_cfg.init_noise_std) > 0:
        raise ValueError(f"ppo.init_noise_std must be > 0 (the sampling std), got {ppo_cfg.init_noise_std}")
    return [restored[0], policy_from_student(restored[1], float(ppo_cfg.init_noise_std)), None]


def sample_count(normalizer, xp=np):
    """The observation normaliser's sample count, float32 (brax keeps it as UInt64 hi/lo or a number); xp: numpy
    on the host, jax.numpy inside the loss."""
    count = normalizer.count
    if hasattr(count, "hi"):
        return xp.asarray(count.hi, xp.float32) * xp.float32(2.0 ** 32) + xp.asarray(count.lo, xp.float32)
    return xp.asarray(count, xp.float32)


def bc_weight(env_steps, weight: float, decay_steps: int):
    """w(n) = weight · max(0, 1 − n / decay_steps) (decay_steps 0: constant)."""
    if decay_steps <= 0:
        return jnp.float32(weight)
    return weight * jnp.maximum(0.0, 1.0 - env_steps / float(decay_steps))


def sample_weights(decayed, in_course, weight: float):
    """Per-sample BC weights with teacher.bc_hold_in_course (module docstring): `weight` where in_course (bool
    per sample, or False: none), `decayed` elsewhere."""
    return jnp.where(in_course, jnp.float32(weight), decayed)


def in_wall_course(data):
    """Which samples of a brax PPO batch come from wall-course episodes: the unified env's "wall_course" metric
    summed over the episode so far (brax's episode_metrics; at least 1 from an episode's first step)."""
    return data.extras["state_extras"]["episode_metrics"]["wall_course"] > 0


def uses_teacher(ppo_cfg) -> bool:
    return float(ppo_cfg.teacher.bc_weight) > 0


class StudentFinetune(PPOExtension):
    """The fine-tune's hooks: the DAgger checkpoint as the first policy, the teacher's waist height in the
    observation and the decaying BC term (module docstring)."""

    def __init__(self, ppo_cfg):
        self._cfg = ppo_cfg

    def initial_params(self, restored, env=None):
        return init_params(restored, self._cfg)

    def state_fields(self, params) -> dict:
        # where the BC term's decay counts from: the normaliser's count when the fine-tune starts
        return {"bc_count_start": float(sample_count(params[0])) if params else 0.0}

    def wrap_env_fn(self, env, full_reset: bool):
        wrap = super().wrap_env_fn(env, full_reset)
        if not uses_teacher(self._cfg):
            return wrap
        observe = teacher_observation(teacher_roles(self._cfg), float(self._cfg.teacher.handover_up_error))
        return lambda inner, **kw: observe(wrap(inner, **kw), env)

    def loss_term(self, env, state: dict):
        return teacher_term(self._cfg, env, float(state.get("bc_count_start", 0.0)))


def extension(ppo_cfg, restored=None) -> PPOExtension:
    """The student fine-tune where the config (a Gaussian policy, a BC term) or the checkpoint it starts from
    (a DAgger student) asks for it, else plain PPO."""
    wanted = ppo_cfg.policy_distribution == NORMAL or uses_teacher(ppo_cfg)
    return StudentFinetune(ppo_cfg) if wanted or (restored is not None and is_student_checkpoint(restored)) \
        else PPOExtension()


def bc_error(mode, label, squashed: bool):
    """The BC error per sample (module docstring); squashed: the mode is tanh(μ), the executed action, already."""
    if squashed:
        return jnp.sum(jnp.square(mode - label), axis=-1)
    return jnp.sum(jnp.square(jnp.tanh(mode) - jnp.tanh(label)), axis=-1)


@contextlib.contextmanager
def teacher_term(ppo_cfg, env, count_start: float):
    """While open, brax's PPO loss carries the BC term (module docstring); a no-op without a teacher."""
    if not uses_teacher(ppo_cfg):
        yield
        return
    t = ppo_cfg.teacher
    squashed = ppo_cfg.policy_distribution != NORMAL          # the mode is tanh(μ) already
    teacher = load_teacher(teacher_roles(ppo_cfg), env.obs_terms, env.manifest_fields()["action_scale"])
    weight, decay = float(t.bc_weight), int(t.bc_decay_steps)
    hold = bool(t.bc_hold_in_course)
    ppo_loss = ppo_losses.compute_ppo_loss

    def loss(params, normalizer_params, data, rng, ppo_network, **kwargs):
        total, metrics = ppo_loss(params, normalizer_params, data, rng, ppo_network, **kwargs)
        logits = ppo_network.policy_network.apply(normalizer_params, params.policy, data.observation)
        mode = ppo_network.parametric_action_distribution.mode(logits)
        label = teacher(data.observation)[1]["loc"]
        bc = bc_error(mode, label, squashed)
        decayed = bc_weight(sample_count(normalizer_params, jnp) - count_start, weight, decay)
        w = sample_weights(decayed, in_wall_course(data) if hold else False, weight)
        metrics = {**metrics, "bc_loss": jnp.mean(bc), "bc_weight": jnp.mean(w)}
        return total + jnp.mean(w * bc), metrics

    ppo_losses.compute_ppo_loss = loss
    try:
        yield
    finally:
        ppo_losses.compute_ppo_loss = ppo_loss

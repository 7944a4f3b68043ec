"""The policy artifacts as the batch evaluations run them, in jax: one artifact (ArtifactPolicy, the file the
runtime runs, through common/observation.py) or the runtime's composite of two (CompositePolicy,
`--policy GETUP,UPRIGHT`, the seed's chapter-6 baseline) or the keyframe getup's latched chain of three
(ChainPolicy, `chain:ROLL,RISE,STAND` or a shipped chain's folder, common/keyframe_chain.py). Used by
training/evaluation/batch.py (getup) and training/evaluation/joystick.py (walking)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from common import events, keyframe_chain
from common import observation as obsdef
from common.artifact import read_artifact
from messages.contract import WAIST_SWITCH_HEIGHT_M

MANIFEST_MUST_MATCH_ENV = ("default_pose", "action_scale", "kp", "kd", "control_dt")
MATCH_TOLERANCE = 1e-6


@dataclass(frozen=True)
class ArtifactPolicy:
    path: Path
    layers: tuple
    obs_mean: np.ndarray
    obs_std: np.ndarray
    manifest: dict

    @classmethod
    def load(cls, path) -> "ArtifactPolicy":
        layers, mean, std, manifest = read_artifact(path)
        return cls(Path(path), tuple(layers), mean, std, manifest)

    @property
    def trained(self) -> bool:
        return bool(self.manifest["trained"])

    def check_env(self, env, keys=MANIFEST_MUST_MATCH_ENV) -> None:
        """The artifact must command the motors the way the env's model does, or the rollout lies."""
        fields = env.manifest_fields()
        for key in keys:
            mine, env_value = np.asarray(self.manifest[key], float), np.asarray(fields[key], float)
            if mine.shape != env_value.shape and mine.size != 1:
                raise ValueError(f"{self.path}: {key} has shape {mine.shape}, the env has {env_value.shape}")
            if np.max(np.abs(mine - env_value)) > MATCH_TOLERANCE:
                raise ValueError(f"{self.path}: manifest {key} differs from the evaluation env's "
                                 f"(max |Δ| = {np.max(np.abs(mine - env_value)):.3g})")

    @property
    def params(self):
        """(layers, obs_mean, obs_std) as a pytree: passed to the jitted rollout as an ARGUMENT, so two
        policies of one shape share one compilation."""
        return (tuple((np.asarray(w), np.asarray(b)) for w, b in self.layers), self.obs_mean, self.obs_std)

    def describe(self) -> str:
        m = self.manifest
        return (f"`{self.path}` name `{m['name']}`, trained: "
                f"**{'yes' if m['trained'] else 'NO (untrained placeholder)'}**, env steps "
                f"{m['provenance']['steps']}, content hash {m['content_hash'][:12]}")

    def initial_last_action(self) -> np.ndarray:
        """The rollout's last-action carry at the first tick (the runtime resets it to 0 entering POLICY)."""
        return np.zeros(obsdef.NUM_JOINTS, np.float32)

    def in_own_map(self, q_target):
        """Joint targets [rad] as this policy's action, clipped to its range (how a composite's idle member
        reads what the other applied)."""
        pose, scale = (jnp.asarray(self.manifest[k], jnp.float32) for k in ("default_pose", "action_scale"))
        return obsdef.targets_to_action(pose, scale, q_target, jnp)

    def follow(self, carry, q_target):
        """The carry of this policy idle in a composite: the applied targets as its last action."""
        del carry
        return self.in_own_map(q_target)

    def act(self, params, obs_state: obsdef.ObservationState, body: dict):
        """One env's tick in jax: (action = the next tick's last action, joint targets [rad]); `body`, the env's
        body_readings (trunk and waist height [m], up_z), is for the policies that switch on them."""
        del body
        action = policy_action(self.manifest, params, obs_state)
        return action, obsdef.action_to_targets(jnp.asarray(self.manifest["default_pose"], jnp.float32),
                                                jnp.asarray(self.manifest["action_scale"], jnp.float32), action)


@dataclass(frozen=True)
class CompositePolicy:
    """The runtime's composite mode (`t1-runtime --policy GETUP --policy-upright UPRIGHT`, the seed's
    chapter-6 baseline): the getup member acts while the waist is below the switch height (0.5 m, the
    stitched teacher's), else the upright (joystick) member, each through its own action map. Each member
    reads its own last action: the acting one its action, the idle one the applied joint targets in its
    map, clipped (runtime/src/policy.cpp `follow`, as the teacher); the rollout carries both members' carries.
    The getup member may be a keyframe chain (`CHAIN_FOLDER,UPRIGHT`): the chain below the switch, the upright
    member above it, as a teacher that kneels would switch."""
    getup: "ArtifactPolicy | ChainPolicy"
    upright: ArtifactPolicy

    # the upright member maps actions around its own pose and scale; it shares the env's motor law only
    UPRIGHT_MUST_MATCH_ENV = ("kp", "kd", "control_dt")

    @classmethod
    def load(cls, spec: str) -> "CompositePolicy":
        parts = [p.strip() for p in str(spec).split(",")]
        if len(parts) != 2 or not all(parts):
            raise ValueError(f"{spec!r}: a composite is GETUP.safetensors,UPRIGHT.safetensors (GETUP may be a "
                             "keyframe chain's folder)")
        getup = ChainPolicy.load(parts[0]) if keyframe_chain.is_chain(parts[0]) else ArtifactPolicy.load(parts[0])
        return cls(getup, ArtifactPolicy.load(parts[1]))

    @property
    def path(self) -> str:
        return f"{self.getup.path},{self.upright.path}"

    @property
    def manifest(self) -> dict:     # control_dt and the like: the getup member's (checked equal to the env's)
        return self.getup.manifest

    @property
    def trained(self) -> bool:
        return self.getup.trained and self.upright.trained

    def check_env(self, env) -> None:
        self.getup.check_env(env)
        self.upright.check_env(env, self.UPRIGHT_MUST_MATCH_ENV)

    @property
    def params(self):
        return (self.getup.params, self.upright.params)

    def describe(self) -> str:
        return (f"composite (getup below waist {WAIST_SWITCH_HEIGHT_M} m, upright above): getup "
                f"{self.getup.describe()}; upright {self.upright.describe()}")

    def initial_last_action(self):
        return (self.getup.initial_last_action(), self.upright.initial_last_action())   # (getup's, upright's)

    def act(self, params, obs_state: obsdef.ObservationState, body: dict):
        own_g, own_u = obs_state.last_action
        c_g, q_g = self.getup.act(params[0], obs_state._replace(last_action=own_g), body)
        a_u, q_u = self.upright.act(params[1], obs_state._replace(last_action=own_u), body)
        use_getup = body["waist_height"] < WAIST_SWITCH_HEIGHT_M
        q_target = jnp.where(use_getup, q_g, q_u)
        next_g = jax.tree.map(lambda acted, idle: jnp.where(use_getup, acted, idle), c_g,
                              self.getup.follow(c_g, q_target))
        return (next_g, jnp.where(use_getup, self.upright.in_own_map(q_target), a_u)), q_target


@dataclass(frozen=True)
class ChainPolicy:
    """The keyframe getup's stages as one latched chain (`chain:ROLL,RISE,STAND`), switched by
    common/events.keyframe_stage: roll until the robot lies face down, rise until §4.8's gate, stand until the
    trunk is down, then roll again; a rise that tipped the robot onto its back or side goes back to the roll.
    Training's teacher and the batch evaluations' reference (it switches on the trunk's height, which only the
    simulation knows). Each member reads its own last action, the idle ones the applied targets in their map (as
    CompositePolicy); the carry is (own actions (3, 23), stage)."""
    members: tuple[ArtifactPolicy, ArtifactPolicy, ArtifactPolicy]
    handover_up_error: float = events.KNEEL_GATE_UP_ERROR   # the rise → stand hand-over (keyframe_stage's)

    PREFIX = "chain:"
    ROLL, RISE, STAND = range(len(events.KEYFRAME_STAGES))

    @classmethod
    def load(cls, spec: str, handover_up_error: float | None = None) -> "ChainPolicy":
        """`chain:ROLL,RISE,STAND` (hand-over at handover_up_error; None: §4.8's gate) or a chain's folder (its
        manifest's hand-over unless handover_up_error says otherwise)."""
        if keyframe_chain.is_chain(spec):
            chain = keyframe_chain.read(spec)
            parts = [str(p) for p in chain.members]
            handover_up_error = chain.handover_up_error if handover_up_error is None else handover_up_error
        else:
            parts = [p.strip() for p in str(spec)[len(cls.PREFIX):].split(",")]
        handover_up_error = events.KNEEL_GATE_UP_ERROR if handover_up_error is None else handover_up_error
        if len(parts) != 3 or not all(parts):
            raise ValueError(f"{spec!r}: a chain is {cls.PREFIX}ROLL.safetensors,RISE.safetensors,STAND.safetensors")
        if not 0 < handover_up_error <= 2:
            raise ValueError(f"handover up error {handover_up_error}: ‖u − e_z‖ of an upright trunk, in (0, 2]")
        return cls(tuple(ArtifactPolicy.load(p) for p in parts), float(handover_up_error))

    @property
    def path(self) -> str:
        return self.PREFIX + ",".join(str(m.path) for m in self.members)

    @property
    def manifest(self) -> dict:
        return self.members[self.RISE].manifest

    @property
    def trained(self) -> bool:
        return all(m.trained for m in self.members)

    def check_env(self, env) -> None:
        for m in self.members:
            m.check_env(env)

    @property
    def params(self):
        return tuple(m.params for m in self.members)

    def describe(self) -> str:
        return (f"chain roll → rise → stand (the rise hands over at ‖u − e_z‖ < {self.handover_up_error:g}): "
                + "; ".join(m.describe() for m in self.members))

    def initial_last_action(self):
        return (np.zeros((3, obsdef.NUM_JOINTS), np.float32), np.int32(events.KEYFRAME_START))

    def follow(self, carry, q_target):
        """The carry of this chain idle in a composite: every member reads the applied targets; the stage goes on
        as its rule said this tick."""
        return jnp.stack([m.in_own_map(q_target) for m in self.members], axis=-2), carry[1]

    def next_stage(self, stage, obs_state: obsdef.ObservationState, body: dict):
        """The stage that acts this tick, from the one that acted the last (common/events.keyframe_stage)."""
        return events.keyframe_stage(stage, events.forward_z_from_quat(obs_state.imu_quat, jnp), body["trunk_height"],
                                     body["up_z"], jnp.linalg.norm(obs_state.gyro, axis=-1), jnp,
                                     self.handover_up_error)

    def act(self, params, obs_state: obsdef.ObservationState, body: dict):
        own, stage = obs_state.last_action
        stage = self.next_stage(stage, obs_state, body)
        out = [m.act(p, obs_state._replace(last_action=own[..., i, :]), body)
               for i, (m, p) in enumerate(zip(self.members, params))]
        q_target = jnp.stack([q for _, q in out])[stage]
        next_own = jnp.stack([jnp.where(stage == i, a, m.in_own_map(q_target))
                              for i, (m, (a, _)) in enumerate(zip(self.members, out))], axis=-2)
        return (next_own, stage), q_target


def load_policy(spec, handover_up_error: float | None = None) -> ArtifactPolicy | CompositePolicy | ChainPolicy:
    """An artifact path, GETUP,UPRIGHT for the runtime's composite of two, or a chain: chain:ROLL,RISE,STAND or a
    shipped chain's folder (its rise hands over to the stand at handover_up_error; None: §4.8's gate, or the
    folder's manifest's hand-over)."""
    if str(spec).startswith(ChainPolicy.PREFIX) or keyframe_chain.is_chain(spec):
        return ChainPolicy.load(spec, handover_up_error)
    if handover_up_error is not None:
        raise ValueError(f"{spec!r}: a hand-over up error is a chain's (chain:ROLL,RISE,STAND or a chain's folder)")
    if Path(spec).is_dir():
        raise ValueError(f"{spec}: a folder, not a policy artifact (nor a keyframe chain: no "
                         f"{keyframe_chain.MANIFEST})")
    return CompositePolicy.load(spec) if "," in str(spec) else ArtifactPolicy.load(spec)


def policy_action(manifest: dict, params, obs_state: obsdef.ObservationState):
    """The artifact's per-tick computation in jax (common/observation.py with xp=jax.numpy)."""
    layers, mean, std = params
    obs = obsdef.build_observation(manifest["obs_terms"], obs_state, jnp)
    return obsdef.policy_forward(layers, obs, mean, std, manifest["activation"], manifest["output_rule"], xp=jnp)

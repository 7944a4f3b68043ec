"""The composite's upright member inside the getup env (getup config `upright_policy`; ours, not the seed's).

The stitched teacher, the runtime's composite and the student all hand the robot to the joystick expert
when the waist rises past WAIST_SWITCH_HEIGHT_M (0.5 m). The getup expert was trained alone, to stand by
itself, so it arrives there mid-lunge, and the joystick expert drops part of those hand-overs: on the loop's
push-test landings a good share of the composite's failed rises fail AFTER the waist passed the switch, and
fine-tuning the joystick expert on hand-over states did not move them (training/LESSONS.md).

With `upright_policy` set, that joystick artifact drives the robot whenever the waist is at or above the
switch height, exactly as the composite does (artifact_policy.CompositePolicy: zero command, the gait clock
frozen, each member reading its own last action, the idle one the applied targets in its map, clipped).
The getup policy's action is then ignored: the joystick expert is part of the world, and the getup
rewards pay for a robot that stands after the hand-over, so the getup expert learns to rise into states
the joystick expert keeps up. Its observation and network are unchanged.

One change to the rewards' gate (§4.8), which this world needs: the seed's per-step gate wants the trunk
within 0.573° of vertical, and the joystick expert stands 1.6° off it (‖u − e_z‖ = 0.028 at rest), so under
it the gate almost never held and a stand after the hand-over paid less than kneeling. While the upright member drives and the robot stands (events'
definition: trunk ≥ 0.6 m, up_z ≥ 0.9) the gate counts as met: the robot is past the kneel by construction.

Fine-tuned this way, the hand-overs got worse (training/LESSONS.md, getup_upright): keep it off until the
policy loss can leave out the steps whose action the member overrides.
"""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from common import observation as obsdef
from training.artifact_policy import ArtifactPolicy, CompositePolicy
from messages.contract import WAIST_SWITCH_HEIGHT_M


class UprightMember:
    """The joystick artifact at `path`, acting above the switch height in `env` (a getup env)."""

    def __init__(self, path: str, env):
        if not str(path).endswith(".safetensors"):
            raise ValueError(f"upright_policy {path!r}: a joystick policy artifact (.safetensors)")
        self.policy = ArtifactPolicy.load(path)
        self.policy.check_env(env, CompositePolicy.UPRIGHT_MUST_MATCH_ENV)
        if [tuple(t) for t in self.policy.manifest["obs_terms"]] == [tuple(t) for t in env.obs_terms]:
            raise ValueError(f"upright_policy {path!r} reads the getup observation: not a joystick expert")
        self._params = self.policy.params
        self._phase = jnp.asarray(obsdef.initial_gait_phase(np), jnp.float32)   # frozen at zero command

    @staticmethod
    def initial_last_action():
        return jnp.zeros(obsdef.NUM_JOINTS)

    def targets(self, env, data, waist_height_m, getup_targets, own_last_action):
        """(joint targets applied this tick [rad], the upright member's next last action): its own targets
        where the waist is at or above the switch height, else the getup policy's."""
        obs_state = env.observation_state(data, jnp.zeros(3), own_last_action, self._phase)
        action, q_upright = self.policy.act(self._params, obs_state, waist_height_m)
        upright = waist_height_m >= WAIST_SWITCH_HEIGHT_M
        q_des = jnp.where(upright, q_upright, getup_targets)
        return q_des, jnp.where(upright, action, self.policy.in_own_map(q_des))

    @staticmethod
    def holds_standing(waist_height_m, standing):
        """Where the upright member has the robot (waist at or above the switch height) and it stands."""
        return (waist_height_m >= WAIST_SWITCH_HEIGHT_M) & standing

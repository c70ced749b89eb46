"""The kinematic baseline of skill transfer: fingertips rigidly attached to the object's motion.

What one tries first when a demonstrated object motion is to be replayed by another hand:
treat the object and the fingertips as one rigid body. At the start of an episode each tip's
position relative to the reference pose is frozen; every control step the tips are driven
to where that rigid attachment carries them along the reference (the reference's position
plus the rotation that takes the initial axis to the reference's axis), by a PD servo in
task space through ``tau = J^T f`` (eq. 30's Jacobian), plus a fixed squeeze along each
contact's (rotated) initial normal, the object's weight shared by the fingers below it, and
the hand's own bias forces H (eq. 35: its weight where the model does not compensate it,
Coriolis and joint damping). There is no grasp model: no W, no internal forces, no friction
cones, no object accelerations. The same skills and metrics as the grip-transform expert
(``ias-gym skills transfer --method kinematic``), so the difference measures what the grasp
model of Theorem 1 buys; the squeeze was chosen per hand on development persons
(:data:`SQUEEZE_BY_HAND`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from ias_gym.baselines.torque_policy import TorquePolicy, rotation_between, side_shares
from ias_gym.envs.pen_hand_env import FloatArray

#: The squeeze per tip of each hand [N]: of 0.15-2.5 N (ias3f: 0.3-2.5 N), the one with the
#: most successes of the transfer test (held, tracked, margin kept) over 58 glove skills of
#: 10 development persons, each scaled into the hand's measured workspace
#: (``train/tune_kinematic.py``; the table is in the CHANGELOG). A hand not listed gets
#: :data:`DEFAULT_SQUEEZE`.
SQUEEZE_BY_HAND: dict[str, float] = {"ias4f": 0.4, "ias3f": 0.75, "shadow": 0.4, "leap": 0.3}
DEFAULT_SQUEEZE = 0.5


@dataclass(frozen=True)
class KinematicGains:
    """Gains of the kinematic baseline (units in the comments)."""

    # 400 N/m and 4 N s/m diverged on the three-finger hand (its 6 mm tips and 7 mm thumb
    # pad): the tips chattered off the pen within 1 s; 300 and 3 hold on both hands.
    kp: float = 300.0  # tip position stiffness [N/m]
    kv: float = 3.0  # tip damping [N s/m]
    # Fixed normal force per tip, on a hand with as many above as below [N]; None: the hand's
    # own from SQUEEZE_BY_HAND.
    squeeze: float | None = None
    #: feed the object's weight forward through the fingers below it, and the hand's own
    #: bias forces H through its joints
    feed_forward: bool = True


class KinematicPolicy(TorquePolicy):
    """``predict(obs) -> (action, None)``: the tips follow the reference as if glued to the pen.

    Privileged like the expert (:class:`~ias_gym.baselines.expert.ExpertPolicy`): it reads
    the unwrapped env's reference, tip positions and Jacobians, and acts only through the
    env's action (normalised torques).

    Args:
        env: an ``IAS-Pen*`` environment with a ``reference()`` (wrappers are looked through).
        gains: servo gains and squeeze.
    """

    def __init__(self, env: gym.Env[Any, Any], gains: KinematicGains | None = None) -> None:
        super().__init__(env, "kinematic baseline")
        self.gains = gains or KinematicGains()
        self.reset()

    def reset(self) -> None:
        """Forget the attachment; the next call freezes the tips' positions anew."""
        self._attached: FloatArray | None = None
        self._normals: FloatArray | None = None
        self._axis0: FloatArray | None = None

    def torques(self) -> FloatArray:
        """Joint torques [N m] for the env's current state and reference."""
        env, g = self.env, self.gains
        p = env.physics
        ref = env.reference()
        contacts = p.fingertip_contacts()
        tips = p.tip_positions()
        if self._attached is None:
            # the tips' places on the demonstrated object, frozen at the start
            self._attached = tips - ref.position
            self._normals = contacts.frames[:, 0].copy()
            # The same total squeeze from above and below, split among the fingers of each
            # side: all the force model the baseline has.
            squeeze = g.squeeze
            if squeeze is None:
                squeeze = SQUEEZE_BY_HAND.get(env.config.hand, DEFAULT_SQUEEZE)
            self._squeeze = squeeze * side_shares(self._normals)
            below = self._normals[:, 1] > 0  # normals point up into the pen from below
            self._below = below / max(int(np.sum(below)), 1)
            self._axis0 = ref.axis.copy()
        assert self._normals is not None and self._axis0 is not None
        R = rotation_between(self._axis0, ref.axis)
        offsets = self._attached @ R.T
        target = ref.position + offsets
        target_velocity = ref.velocity + np.cross(ref.omega, offsets)
        # J maps joint rates to each contact point's velocity along its (n, t1, t2) rows;
        # frames^T turns those rows back into the paper frame.
        J = p.fingertip_jacobians(contacts).reshape(-1, 3, p.n_hand_dofs)
        J_world = np.einsum("kji,kjn->kin", contacts.frames, J)
        tip_velocity = np.einsum("kin,n->ki", J_world, p.hand_qvel())
        force = g.kp * (target - tips) + g.kv * (target_velocity - tip_velocity)
        force += self._squeeze[:, None] * (self._normals @ R.T)
        if g.feed_forward:
            # the pen's weight carried by the fingers below it, equally (paper y is up)
            force[:, 1] -= self._below * p.pen_mass_nominal * float(env.model.opt.gravity[2])
        tau: FloatArray = np.einsum("kin,ki->n", J_world, force)
        if g.feed_forward:
            tau = tau + p.hand_bias_forces()
        return tau

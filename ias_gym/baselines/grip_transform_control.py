"""Grip-transform control of the pen (paper section 3.3), on the simulated hand.

Each control step:

1. the object's desired acceleration from a PD law on the pose error plus the reference's
   feed-forward (eqs. 26-28, 43): ``a_d = r''_d - Kv e_v - Kp e_p``; the orientation error is
   taken from the pen's axis (``e_R = axis x axis_d``), so nothing depends on the pen's roll
   about itself (its roll inertia is ~20x smaller than its pitch inertia: any roll-dependent
   term spins it up, DESIGN.md);
2. the wrench the fingers must apply, from the object's Newton-Euler equations (eq. 33):
   ``W c = [m a_d; I alpha_d + omega x I omega] - w_g``;
3. the wrench intensities c that realise it with the least grasp force, inside the friction
   cones, with normals >= f0 and the sliding finger on its cone (eqs. 19-24, the fast
   :class:`~ias_gym.grasp.internal_forces.InternalForceSolver`); W is rebuilt from the
   measured contacts every step (soft contacts move the points);
4. joint torques ``tau = J^T (c + f_slide) + H`` (eqs. 30, 35), where ``f_slide`` is a PD
   force along the pen that moves a sliding finger's tip along its schedule (eq. 17) and
   ``H`` the fingers' bias forces.

This is the quasi-static core of Theorem 1 (eq. 45): it keeps the ``M* Psi`` object terms
and the ``J^T c`` internal-force term, and drops the finger-inertia terms ``M J+ {...}``,
which matter little for fingers of 5-15 g.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ias_gym.envs.pen_hand_env import FloatArray, PenHandEnv, PenReference
from ias_gym.grasp.internal_forces import (
    InfeasibleGraspError,
    InternalForceSettings,
    InternalForceSolver,
)


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


@dataclass(frozen=True)
class ControllerGains:
    """Gains of the grip-transform controller (units in the comments)."""

    kp: float = 400.0  # pen position stiffness [1/s^2]
    kv: float = 40.0  # pen position damping [1/s]
    kp_rot: float = 400.0  # pen orientation stiffness [1/s^2]
    kv_rot: float = 40.0  # pen orientation damping [1/s]
    kp_slide: float = 30.0  # sliding-finger tip stiffness along the pen [N/m]
    kv_slide: float = 0.5  # sliding-finger tip damping [N s/m]
    kp_lateral: float = 20.0  # tip stiffness across the pen, toward its top/bottom line [N/m]
    kv_lateral: float = 0.5  # tip damping across the pen [N s/m]
    friction_margin: float = 0.2  # sticking contacts use mu (1 - margin) [-]
    mu: float = 0.25  # friction coefficient the controller assumes [-]


@dataclass
class GripTransformController:
    """Joint torques for the pen hand from the grasp model (see the module docstring).

    Args:
        f0: minimum normal force [N] (the task's ``min_grasp_force``).
        gains: controller gains.
    """

    f0: float = 0.2
    gains: ControllerGains = field(default_factory=ControllerGains)
    infeasible_count: int = 0

    def __post_init__(self) -> None:
        settings = InternalForceSettings(
            mu=self.gains.mu, f0=self.f0, margin=self.gains.friction_margin
        )
        # A regulariser of 1e-2 /N (not the solver's 1e-6) picks the least-norm solution
        # among equal sums of normals: the smaller one left the top fingers squeezing the pen
        # along its axis with 0.04 N at their friction limit, and MuJoCo's soft friction let
        # them creep 3 mm in 0.5 s (measured). Soft contacts creep under any shear, so the
        # controller asks for no shear it does not need.
        self._solver = InternalForceSolver(4, settings, regularisation=1e-2)
        self._last_c = np.tile([self.f0, 0.0, 0.0], 4)

    def desired_wrench(self, env: PenHandEnv, ref: PenReference) -> FloatArray:
        """The net wrench the fingers must apply to the pen (eqs. 28, 33, 43) [N, N m]."""
        g = self.gains
        p = env.physics
        position, _ = p.pen_pose()
        v, omega = p.pen_twist()
        axis = p.pen_axis()
        acc = ref.acceleration - g.kv * (v - ref.velocity) - g.kp * (position - ref.position)
        # Orientation: roll about the pen's own axis is left free.
        omega_perp = omega - (omega @ axis) * axis
        alpha = ref.alpha + g.kp_rot * _cross(axis, ref.axis) - g.kv_rot * (omega_perp - ref.omega)
        inertia = p.pen_inertia()
        mass = p.pen_mass()
        gravity = -9.81 * mass * np.array([0.0, 1.0, 0.0])
        force = mass * acc - gravity
        moment = inertia @ alpha + _cross(omega, inertia @ omega)
        return np.concatenate([force, moment])

    def torques(self, env: PenHandEnv) -> FloatArray:
        """Joint torques [N m] for the env's current state and reference."""
        p = env.physics
        ref = env.reference()
        contacts = p.fingertip_contacts()
        W, active = p.wrench_matrix(contacts)
        J = p.fingertip_jacobians(contacts)
        w_des = self.desired_wrench(env, ref)
        sliding = {k: s for k, s in ref.sliding.items() if active[k]}
        try:
            c = self._solver.solve(W, -w_des, sliding).c
            self._last_c = c
        except InfeasibleGraspError:
            self.infeasible_count += 1
            c = self._last_c
        f = c.copy()
        f[2::3] += self._lateral_servo(env, contacts.frames, J)
        if sliding and ref.contact_x is not None and ref.contact_vx is not None:
            g = self.gains
            slide = np.zeros(4)
            slide[list(sliding)] = 1.0
            tips = p.tip_positions() - p.pen_com()
            x = tips @ p.pen_axis()
            v_pen, _ = p.pen_twist()
            # Velocity of each tip along the pen (relative to the pen's centre), from J.
            vx = (J[1::3] @ p.hand_qvel()) - v_pen @ p.pen_axis()
            f[1::3] += slide * (
                g.kp_slide * (ref.contact_x - x) + g.kv_slide * (ref.contact_vx - vx)
            )
        # H of eq. (35): Coriolis/centrifugal forces (gravity is compensated by the model's
        # gravcomp). The joints' passive damping is deliberately NOT cancelled: sampled and
        # held for a control period, a cancellation turns into negative damping of the
        # grasp's roll mode (tips circling the pen, which rolls with them), which nothing else
        # damps; measured: the pen's roll rate doubled every 0.2 s and it fell after 1.2 s.
        d = env.data
        dofs = p.hand_dof_ids
        coriolis = d.qfrc_bias[dofs] - d.qfrc_gravcomp[dofs]
        return J.T @ f + coriolis

    def _lateral_servo(self, env: PenHandEnv, frames: FloatArray, J: FloatArray) -> FloatArray:
        """Forces along t2 [N] that keep each tip on the pen's top or bottom line.

        Without them nothing holds the tips from circling the pen (the pen rolls with them at
        no cost), and they drift until the grasp breaks. The lateral direction is built from
        the vertical and the pen's axis, never from the pen's own (rolling) frame.
        """
        g = self.gains
        p = env.physics
        axis = p.pen_axis()
        lateral = _cross(np.array([0.0, 1.0, 0.0]), axis)
        lateral /= np.linalg.norm(lateral)
        v_pen, _ = p.pen_twist()
        sign = frames[:, 2] @ lateral  # t2 is +-lateral
        offset = (p.tip_positions() - p.pen_com()) @ lateral
        rate = sign * (J[2::3] @ p.hand_qvel()) - v_pen @ lateral
        return -sign * (g.kp_lateral * offset + g.kv_lateral * rate)

    def action(self, env: PenHandEnv) -> FloatArray:
        """The env action (normalised torques) for the current state."""
        tau = self.torques(env)
        return np.clip(tau / env._ctrl_max, -1.0, 1.0)

"""The grip-transform control law of Theorem 1 (paper section 3.3, eq. 45) on the MuJoCo hand.

:class:`GripTransformController` is the adapter: it reads the physics (contacts, W, J, M,
the pen's state, the task's reference) and calls the law's terms, pure functions on arrays in
:mod:`ias_gym.baselines.law`; the servos beyond the paper and the memory of the previous step
(W and J for their rates, the last feasible LP solution, N) stay here.

Every control step (``control_dt``), from the measured contacts:

- **Object motion** (eqs. 26-28, 41, 43): the desired object acceleration
  ``a_d = [r''_d - Kv e_v - Kp e_p ; omega'_d - Kv e_omega - Kp e_R]``. The orientation error
  is taken on the pen's axis, ``e_R = axis_d x axis``, in angular-velocity coordinates: this is
  eq. (41) with ``Psi = I`` for the rotation (the paper's roll-pitch-yaw ``Psi(phi)`` adds
  ``Psi'`` terms and a singularity at pitch +-90 deg), and it leaves the roll about the pen's
  own axis free (its roll inertia is ~20x smaller than its pitch inertia: any roll-dependent
  term spins the pen up, docs/DESIGN.md).
- **Object dynamics** (eq. 33): the net contact wrench ``w = [m a_d; I alpha_d + omega x I omega]
  - w_g``. The paper's eq. (33) has no gravity (its ``f_ext`` is the contact wrench); the pen's
  weight ``w_g`` (eq. 18) is added here, so ``c_p = W+ w`` (eqs. 5, 36).
- **Internal forces** (eqs. 19-24, 29, 44): the reference ``c_h^d`` is the internal part of the
  minimum-grasp-force solution with the friction cones, solved every step by the fast
  :class:`~ias_gym.grasp.internal_forces.InternalForceSolver` with W rebuilt from the
  measured contacts (soft contacts move the points). The law's term
  ``J^T [c_h^d - (1/delta) e_f' - (1/delta) W+ W' e_f]`` prescribes that the measured
  internal-force error ``e_f = c_h - c_h^d`` obeys ``e_f' = -(delta I + W+ W') e_f`` (eq. 44). In
  the paper's rigid model ``c_h`` follows the torques instantly; with a measured ``e_f'`` the
  term would be an algebraic loop. The code therefore commands the internal forces one
  explicit-Euler step of eq. (44) ahead: ``c_h_cmd = c_h^d + (I - dt (delta I + W+ W')) e_f``;
  wherever the soft contacts deliver the commanded force within a control period, the
  closed loop follows eq. (44) with rate ``delta`` (``delta dt = 1`` commands ``c_h^d``
  directly).
- **Fingers** (eqs. 30-32, 35, 39, 45): ``tau = J^T (c_p + c_h_cmd) + H + M J+ (W^T a_d + W'^T v -
  J' theta')`` — the second half of ``M* a_d`` (eq. 39) and the ``M J+ {...}`` term of eq. (45),
  with ``v_int = 0`` (a rigid pen), ``J+`` a damped pseudo-inverse, and ``J' theta'`` (the
  scan's ``J theta'`` lost its dot; eqs. 31-32 have ``J'``). ``W'`` and ``J'`` are finite
  differences over one control period.

Beyond the paper, where its assumptions do not hold in the simulation:

- a sliding finger (the skill of 3.2) is driven along its schedule by a PD force along the pen
  on top of its kinetic friction ``mu c_n`` (the LP's equality, docs/NOTES.md); the paper's model
  has the contact points move through W(t) but no law for the finger's own motion;
- each tip is held on the pen's top or bottom line by a PD force across the pen: nothing in the
  grasp model resists the tips circling the pen (the pen rolls with them at no cost);
- ``H`` has Coriolis/centrifugal terms only (gravity is compensated by the model's gravcomp);
  the joints' passive damping is left in place (see :meth:`GripTransformController.torques`);
- the LP's solution is the least-norm one among equal sums of normal forces, because MuJoCo's
  soft friction lets any shear creep.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ias_gym.baselines import law
from ias_gym.envs.pen_hand_env import FloatArray, PenHandEnv, PenReference
from ias_gym.grasp.contacts import cross3
from ias_gym.grasp.grasp_margin import scale_to_margin
from ias_gym.grasp.grip_transform import null_space_basis, pseudo_inverse
from ias_gym.grasp.internal_forces import (
    Cone,
    InfeasibleGraspError,
    InternalForceSettings,
    InternalForceSolver,
)
from ias_gym.sim.pen_hand import mj_to_paper

NDArrayBool = np.ndarray


@dataclass(frozen=True)
class ControllerGains:
    """Gains of the grip-transform controller (units in the comments)."""

    kp: float = 400.0  # object position stiffness Kp [1/s^2] (eq. 43)
    kv: float = 40.0  # object position damping Kv [1/s]
    kp_rot: float = 400.0  # object orientation stiffness [1/s^2]
    kv_rot: float = 40.0  # object orientation damping [1/s]
    delta: float = 50.0  # internal-force error rate delta of eq. (44) [1/s]
    kp_slide: float = 30.0  # sliding-finger tip stiffness along the pen [N/m]
    kv_slide: float = 0.5  # sliding-finger tip damping [N s/m]
    kp_lateral: float = 20.0  # tip stiffness across the pen, toward its top/bottom line [N/m]
    kv_lateral: float = 1.5  # tip damping across the pen [N s/m]
    friction_margin: float = 0.4  # sticking contacts use mu (1 - margin) [-]
    mu: float = 0.25  # friction coefficient the controller assumes [-]
    cone: Cone = "polygon"  # friction cone of the internal-force problem: box or polygon
    jacobian_damping: float = 1e-6  # damping of J+ [m^2]
    finger_inertia: bool = True  # include the M J+ {...} terms of eq. (45)
    lead: float = 0.0  # evaluate the reference this far ahead [s]
    damping_feedforward: bool = True  # add the joints' damping along the reference motion


@dataclass
class ControlStep:
    """What one control step computed (for diagnostics, figures and tests; paper frame)."""

    tau: FloatArray  # joint torques [N m]
    wrench: FloatArray  # net contact wrench the object needs [N, N m]
    c_h_desired: FloatArray  # internal-force reference c_h^d [N]
    c_h_measured: FloatArray  # measured internal forces c_h [N]
    c_command: FloatArray  # commanded intensities c_p + c_h_cmd [N]
    active: NDArrayBool  # fingers in contact
    feasible: bool  # the internal-force problem had a solution this step
    offset_scale: float = 1.0  # fraction of the requested internal-force offset the cones allowed
    error_scale: float = 1.0  # fraction of eq. (44)'s step of e_f the cones allowed


@dataclass
class GripTransformController:
    """Joint torques of Theorem 1 for an ``IAS-Pen*`` env (see the module docstring).

    Args:
        f0: minimum normal force [N] (the task's ``min_grasp_force``).
        gains: controller gains.

    Attributes:
        infeasible_count: control steps whose internal-force problem had no solution (the
            last feasible solution was used instead).
        last: what the last call computed.
    """

    f0: float = 0.2
    gains: ControllerGains = field(default_factory=ControllerGains)
    infeasible_count: int = 0
    last: ControlStep | None = None

    def __post_init__(self) -> None:
        settings = InternalForceSettings(
            mu=self.gains.mu, f0=self.f0, margin=self.gains.friction_margin, cone=self.gains.cone
        )
        # A regulariser of 1e-2 /N (not the solver's 1e-6) picks the least-norm solution
        # among equal sums of normals: the smaller one left the top fingers squeezing the pen
        # along its axis with 0.04 N at their friction limit, and MuJoCo's soft friction let
        # them creep 3 mm in 0.5 s (measured). Soft contacts creep under any shear, so the
        # controller asks for no shear it does not need.
        self._solver = InternalForceSolver(4, settings, regularisation=1e-2)
        self._last_c = np.tile([self.f0, 0.0, 0.0], 4)
        self._prev_W: FloatArray | None = None
        self._prev_J: FloatArray | None = None
        self._N: FloatArray | None = None
        self._extra = np.zeros(12)  # servo forces commanded last step [N]
        self._joint_damping: FloatArray | None = None
        self._gravity: FloatArray | None = None  # the model's, paper frame [m/s^2]

    def object_acceleration(self, env: PenHandEnv, ref: PenReference) -> FloatArray:
        """Desired object acceleration ``[v'; omega']`` of eqs. (41), (43) [m/s^2, rad/s^2].

        :func:`ias_gym.baselines.law.object_acceleration` with this controller's gains.

        Args:
            env: the unwrapped environment (its measured pen state).
            ref: the reference to track.
        """
        g = self.gains
        return law.object_acceleration(
            env.state, ref, kp=g.kp, kv=g.kv, kp_rot=g.kp_rot, kv_rot=g.kv_rot
        )

    def object_wrench(self, env: PenHandEnv, a_d: FloatArray) -> FloatArray:
        """Net contact wrench [N, N m] for acceleration ``a_d`` (eq. 33 plus the weight, eq. 18).

        :func:`ias_gym.baselines.law.object_wrench` with the model's pen as built (a
        controller does not know a disturbed mass) and the model's gravity.

        Args:
            env: the unwrapped environment.
            a_d: ``(6,)`` desired object acceleration [m/s^2, rad/s^2].
        """
        p = env.physics
        if self._gravity is None:
            self._gravity = mj_to_paper(env.model.opt.gravity)
        return law.object_wrench(
            p.pen_mass_nominal, p.pen_inertia(nominal=True), env.state.omega, a_d, self._gravity
        )

    def torques(
        self,
        env: PenHandEnv,
        accel_offset: FloatArray | None = None,
        internal_offset: FloatArray | None = None,
    ) -> FloatArray:
        """Joint torques [N m] of eq. (45) for the env's current state and reference.

        Args:
            env: the unwrapped environment.
            accel_offset: added to the desired object acceleration ``a_d`` (6,)
                [m/s^2, rad/s^2].
            internal_offset: added to the internal forces ``f_int`` of the reference,
                ``c_h^d += N offset`` (6,) [N] (eq. 7; N kept continuous along the episode).
        """
        g = self.gains
        p = env.physics
        if p.n_fingers != self._solver.n_contacts:  # a hand other than the four-finger one
            self._solver = InternalForceSolver(p.n_fingers, self._solver.settings, 1e-2)
            self._last_c = np.tile([self.f0, 0.0, 0.0], p.n_fingers)
            self._extra = np.zeros(3 * p.n_fingers)
        dt = env.config.control_dt
        ref = _ahead(env.reference(), g.lead)
        contacts = p.fingertip_contacts()
        W, active = p.wrench_matrix(contacts)
        J = p.fingertip_jacobians(contacts)
        c_measured = p.contact_intensities(contacts)
        qvel = p.hand_qvel()
        tips = p.tip_positions()
        tip_x = env.state.tip_x
        noise = env.sensor_noise
        if noise is not None:  # the expert measures through the task's sensor noise
            touching = np.repeat(active, 3)
            c_measured = np.where(
                touching, noise.contact_intensities(c_measured, contacts.frames), 0.0
            )
            qvel = qvel + noise.qvel
            tips = tips + noise.tip_displacement(J, contacts.frames)
            tip_x = tip_x + (tips - p.tip_positions()) @ env.state.axis
        task_offset = env.internal_force_reference()
        if task_offset is not None:
            internal_offset = (
                task_offset if internal_offset is None else internal_offset + task_offset
            )

        a_d = self.object_acceleration(env, ref)
        if accel_offset is not None:
            a_d = a_d + accel_offset
        wrench = self.object_wrench(env, a_d)
        sliding = {k: s for k, s in ref.sliding.items() if active[k]}
        try:
            c_ref = self._solver.solve(W, -wrench, sliding).c
            self._last_c = c_ref
            feasible = True
        except InfeasibleGraspError:
            self.infeasible_count += 1
            c_ref = self._last_c
            feasible = False

        # Grip transform of the measured W (eqs. 5, 7): c = c_p + c_h.
        W_pinv = pseudo_inverse(W, least_squares_if_singular=True)
        dW = np.zeros_like(W) if self._prev_W is None else (W - self._prev_W) / dt
        c_p = W_pinv @ wrench
        c_h_d = law.internal_part(c_ref, W, W_pinv)
        margin_reference = getattr(env, "grasp_margin_reference", None)
        if margin_reference is not None and bool(active.all()):
            # A skill's grasp margin (IAS-PenSkill-v0, docs/transfer.md): the hand's own
            # internal forces, scaled so that c_p + c_h^d has the demonstrated margin.
            c_h_d = scale_to_margin(c_p, c_h_d, float(margin_reference()), self.gains.mu)
        settings = self._solver.settings
        offset_scale = 1.0
        if internal_offset is not None and np.any(internal_offset):
            self._N = null_space_basis(W, self._N) if bool(active.all()) else self._N
            if self._N is not None:
                # A requested offset is taken only as far as the cones allow (a squeeze that
                # opens a contact or pushes one out of its cone would drop the object).
                offset = law.keep_sliding_friction(self._N, internal_offset, sliding, settings.mu)
                offset_scale = law.largest_step_inside_cones(
                    c_p + c_h_d, offset, active, sliding, settings
                )
                c_h_d = c_h_d + offset_scale * offset
        # The servo forces below (lateral, sliding) are part of what the contacts carry but not
        # of the grasp model's c; left in the measurement, eq. (44) would feed them back and
        # amplify them by 1 / (delta dt) (measured: at delta dt = 0.25 the grasp broke).
        c_model = c_measured - self._extra
        c_h = law.internal_part(c_model, W, W_pinv)
        e_f = c_h - c_h_d
        # One explicit-Euler step of eq. (44): e_f' = -(delta I + W+ W') e_f.
        step = law.internal_force_step(e_f, W_pinv, dW, g.delta, dt)
        error_scale = law.largest_step_inside_cones(c_p + c_h_d, step, active, sliding, settings)
        c_h_cmd = c_h_d + error_scale * step
        c_cmd = c_p + c_h_cmd

        extra = np.zeros_like(c_cmd)
        extra[2::3] = self._lateral_servo(env, contacts.frames, J, qvel, tips)
        if sliding and ref.contact_x is not None and ref.contact_vx is not None:
            extra[1::3] = self._slide_servo(env, ref, sliding, J, qvel, tip_x)
        self._extra = extra
        f = c_cmd + extra

        # H of eq. (35): Coriolis/centrifugal forces (gravity is compensated by the model's
        # gravcomp). The joints' passive damping is deliberately NOT cancelled: sampled and
        # held for a control period, a cancellation turns into negative damping of the
        # grasp's roll mode (tips circling the pen, which rolls with them), which nothing else
        # damps; measured: the pen's roll rate doubled every 0.2 s and it fell after 1.2 s.
        d = env.data
        dofs = p.hand_dof_ids
        coriolis = d.qfrc_bias[dofs] - d.qfrc_gravcomp[dofs]
        inertia = feedforward = None
        if g.finger_inertia or g.damping_feedforward:
            J_pinv = law.damped_pinv_blocks(J, g.jacobian_damping)
            touching = np.repeat(active, 3)
        if g.finger_inertia:
            # J' over one control period; zero on the first step (no previous J).
            dJ = np.zeros_like(J) if self._prev_J is None else (J - self._prev_J) / dt
            v = np.concatenate([env.state.velocity, env.state.omega])
            inertia = law.finger_inertia_torques(
                p.hand_mass_matrix(), J_pinv, W, dW, dJ, qvel, a_d, v, touching
            )
        if g.damping_feedforward:
            # The joints' damping along the *reference* motion (never the measured one, which
            # would cancel the damping, see above): fingers that follow the object drag on
            # it otherwise (measured: a 23 ms lag of the pen's tilt behind its reference).
            v_ref = np.concatenate([ref.velocity, ref.omega])
            feedforward = law.damping_feedforward_torques(
                self._damping(env), J_pinv, W, v_ref, touching
            )
        tau = law.joint_torques(J, f, coriolis, inertia, feedforward)

        self._prev_W, self._prev_J = W, J
        self.last = ControlStep(
            tau, wrench, c_h_d, c_h, c_cmd, active, feasible, offset_scale, error_scale
        )
        return tau

    def _damping(self, env: PenHandEnv) -> FloatArray:
        """The hand joints' damping coefficients [N m s/rad] (looked up once)."""
        if self._joint_damping is None:
            self._joint_damping = env.model.dof_damping[env.physics.hand_dof_ids].copy()
        return self._joint_damping

    def _lateral_servo(
        self, env: PenHandEnv, frames: FloatArray, J: FloatArray, qvel: FloatArray, tips: FloatArray
    ) -> FloatArray:
        """Forces along t2 [N] that keep each tip on the pen's top or bottom line.

        Without them nothing holds the tips from circling the pen (the pen rolls with them at
        no cost), and they drift until the grasp breaks. The lateral direction is built from
        the vertical and the pen's axis, never from the pen's own (rolling) frame.
        """
        g = self.gains
        s = env.state
        x, _, z = s.axis.tolist()
        norm = np.hypot(x, z)
        lateral = np.array([z / norm, 0.0, -x / norm])  # up x axis, normalised
        sign = frames[:, 2] @ lateral  # t2 is +-lateral
        offset = (tips - s.position) @ lateral
        rate = sign * (J[2::3] @ qvel) - s.velocity @ lateral
        result: FloatArray = -sign * (g.kp_lateral * offset + g.kv_lateral * rate)
        return result

    def _slide_servo(
        self,
        env: PenHandEnv,
        ref: PenReference,
        sliding: dict[int, FloatArray],
        J: FloatArray,
        qvel: FloatArray,
        tip_x: FloatArray,
    ) -> FloatArray:
        """Forces along t1 [N] that move sliding tips along their schedule (eq. 17)."""
        assert ref.contact_x is not None and ref.contact_vx is not None
        g = self.gains
        s = env.state
        mask = np.zeros(len(tip_x))
        mask[list(sliding)] = 1.0
        # Velocity of each tip along the pen relative to the pen's centre, from J.
        vx = J[1::3] @ qvel - s.velocity @ s.axis
        error = ref.contact_x - tip_x
        result: FloatArray = mask * (g.kp_slide * error + g.kv_slide * (ref.contact_vx - vx))
        return result

    def action(
        self,
        env: PenHandEnv,
        accel_offset: FloatArray | None = None,
        internal_offset: FloatArray | None = None,
    ) -> FloatArray:
        """The env action (normalised torques, clipped to [-1, 1]); see :meth:`torques`."""
        tau = self.torques(env, accel_offset, internal_offset)
        return np.clip(tau / env._ctrl_max, -1.0, 1.0)


def _ahead(ref: PenReference, lead: float) -> PenReference:
    """The reference ``lead`` seconds ahead, extrapolated with its own derivatives."""
    if lead == 0.0:
        return ref
    axis = ref.axis + lead * cross3(ref.omega, ref.axis)
    return PenReference(
        position=ref.position + lead * ref.velocity + 0.5 * lead**2 * ref.acceleration,
        velocity=ref.velocity + lead * ref.acceleration,
        acceleration=ref.acceleration,
        axis=axis / np.linalg.norm(axis),
        omega=ref.omega + lead * ref.alpha,
        alpha=ref.alpha,
        sliding=ref.sliding,
        contact_x=ref.contact_x,
        contact_vx=ref.contact_vx,
    )

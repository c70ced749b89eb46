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
  soft friction lets any shear creep;
- where the motors saturate, the holding torques ``J^T f + H`` come first and the motion
  terms are scaled down together (:func:`~.grip_transform_terms.motion_share`);
- a skill's squeeze is never below a share of what each finger's sticking joints let it set
  (:func:`~.grip_transform_terms.resolvable_squeeze`; hands with joint friction only).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ias_gym.baselines import law
from ias_gym.baselines.friction_estimate import FrictionEstimate
from ias_gym.baselines.gains import ControllerGains
from ias_gym.baselines.grip_transform_terms import (
    ControlStep,
    Gathered,
    MotionRows,
    ReferenceRows,
    ahead,
    damping_feedforward,
    estimated_masses,
    lateral_servo,
    resolvable_squeeze,
    right_inverses,
    slide_servo,
    slip_speeds,
    with_motion,
)
from ias_gym.envs.pen_hand_env import FloatArray, PenHandEnv, PenReference
from ias_gym.grasp.grasp_margin import scale_to_margin
from ias_gym.grasp.grip_transform import null_space_basis
from ias_gym.grasp.internal_forces import (
    InfeasibleGraspError,
    InternalForceSettings,
    InternalForceSolver,
)
from ias_gym.grasp.wrench_matrix import wrench_matrices
from ias_gym.sim.pen_hand import mj_to_paper

NDArrayBool = np.ndarray


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
        self._settings = InternalForceSettings(
            mu=self.gains.mu, f0=self.f0, margin=self.gains.friction_margin, cone=self.gains.cone
        )
        # Sized for the env's fingers on the first control step (_bind).
        self._solver: InternalForceSolver | None = None
        self._last_c: FloatArray | None = None  # the last feasible solution [N]
        self._extra: FloatArray | None = None  # servo forces commanded last step [N]
        self._prev_W: FloatArray | None = None
        self._prev_J: FloatArray | None = None
        self._integral = np.zeros(3)  # integral of the position error [m s]
        self._mass: float | None = None  # the estimated pen mass [kg] (None: not yet)
        g = self.gains  # what the tips show
        self._friction = FrictionEstimate(g.slip_time, g.plateau_time, g.plateau_tolerance)
        self._estimates_friction = False  # set on binding to a skill's env
        self._N: FloatArray | None = None
        self._joint_damping: FloatArray | None = None
        self._gravity: FloatArray | None = None  # the model's, paper frame [m/s^2]

    @property
    def friction(self) -> float:
        """The friction coefficient a skill's squeeze is planned with now [-]: what the tips
        have shown (``gains.slip_speed``, :class:`~.friction_estimate.FrictionEstimate`),
        else the nominal ``gains.mu``."""
        return self._friction.value or self.gains.mu

    def _bind(self, env: PenHandEnv) -> InternalForceSolver:
        """The internal-force solver for the env's fingers (built on the first step)."""
        if self._solver is None:
            k = env.physics.n_fingers
            # A regulariser of 1e-2 /N (not the solver's 1e-6) picks the least-norm solution
            # among equal sums of normals: the smaller one left the top fingers squeezing the
            # pen along its axis with 0.04 N at their friction limit, and MuJoCo's soft
            # friction let them creep 3 mm in 0.5 s (measured). Soft contacts creep under any
            # shear, so the controller asks for no shear it does not need.
            self._solver = InternalForceSolver(k, self._settings, regularisation=1e-2)
            # only a skill's squeeze (a margin to keep) reads the friction estimate
            self._estimates_friction = hasattr(env, "grasp_margin_reference")
            self._last_c = np.tile([self.f0, 0.0, 0.0], k)
            self._extra = np.zeros(3 * k)
        return self._solver

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
        return law.object_wrench(
            p.pen_mass_nominal, p.pen_inertia(nominal=True), env.state.omega, a_d, self._g(env)
        )

    def _g(self, env: PenHandEnv) -> FloatArray:
        """The model's gravity [m/s^2], paper frame (looked up once)."""
        if self._gravity is None:
            self._gravity = mj_to_paper(env.model.opt.gravity)
        return self._gravity

    def torques(
        self,
        env: PenHandEnv,
        accel_offset: FloatArray | None = None,
        internal_offset: FloatArray | None = None,
    ) -> FloatArray:
        """Joint torques [N m] of eq. (45) for the env's current state and reference.

        :func:`batch_torques` for this one env (the same computation, bit for bit).

        Args:
            env: the unwrapped environment.
            accel_offset: added to the desired object acceleration ``a_d`` (6,)
                [m/s^2, rad/s^2].
            internal_offset: added to the internal forces ``f_int`` of the reference,
                ``c_h^d += N offset`` (6,) [N] (eq. 7; N kept continuous along the episode).
        """
        accel = None if accel_offset is None else np.asarray(accel_offset)[None]
        tau: FloatArray = batch_torques([self], [env], accel, [internal_offset])[0]
        return tau

    def _damping(self, env: PenHandEnv) -> FloatArray:
        """The hand joints' damping coefficients [N m s/rad] (looked up once)."""
        if self._joint_damping is None:  # viscous and Coulomb, (2, n)
            p = env.physics
            self._joint_damping = np.stack([p.hand_damping(), p.hand_damping(coulomb=True)])
        return self._joint_damping

    def action(
        self,
        env: PenHandEnv,
        accel_offset: FloatArray | None = None,
        internal_offset: FloatArray | None = None,
    ) -> FloatArray:
        """The env action (normalised torques, clipped to [-1, 1]); see :meth:`torques`."""
        tau = self.torques(env, accel_offset, internal_offset)
        return np.clip(tau / env._ctrl_max, -1.0, 1.0)


def batch_torques(
    controllers: Sequence[GripTransformController],
    envs: Sequence[PenHandEnv],
    accel_offsets: FloatArray | None = None,
    internal_offsets: Sequence[FloatArray | None] | None = None,
) -> FloatArray:
    """Joint torques of eq. (45) [N m], ``(n, n_hand_dofs)``: ``controllers[i]`` on ``envs[i]``.

    The control step of :meth:`GripTransformController.torques` for ``n`` envs at once: each
    env's physics is read (contacts, J, M, the reference) and its internal-force problem
    solved on its own, and the dense linear algebra in between (W, W+, the law's terms of
    :mod:`~ias_gym.baselines.law`, the cone limiter, J+, the servos) runs once for all envs,
    numpy over the env axis. Each row equals that env's own control step bit for bit.

    Args:
        controllers: one controller per env (its memory is updated), all with equal gains.
        envs: the unwrapped environments, all with the same hand.
        accel_offsets: ``(n, 6)`` added to each desired object acceleration ``a_d``
            [m/s^2, rad/s^2] (``None``: none).
        internal_offsets: per env the offset of the internal forces ``f_int`` (6,) [N] or
            ``None`` (see :meth:`GripTransformController.torques`).

    Raises:
        ValueError: the controllers' gains differ, or the lengths do not match.
    """
    n = len(envs)
    if len(controllers) != n or n == 0:
        raise ValueError(f"need one controller per env, got {len(controllers)} for {n} envs")
    g = controllers[0].gains
    if any(c.gains is not g and c.gains != g for c in controllers):
        raise ValueError("batch_torques needs controllers with equal gains")
    k = envs[0].physics.n_fingers
    if any(env.physics.n_fingers != k for env in envs):
        raise ValueError("batch_torques needs envs of one hand (the same number of fingers)")
    rows: list[tuple[Any, ...]] = []
    scalars: list[tuple[Any, ...]] = []
    refs: list[PenReference] = []
    offsets: list[FloatArray | None] = []
    margins: list[float | None] = []
    slides: list[dict[int, FloatArray]] = []
    for i, (ctrl, env) in enumerate(zip(controllers, envs, strict=True)):
        ctrl._bind(env)
        p = env.physics
        ref = ahead(env.reference(), g.lead)
        refs.append(ref)
        contacts = p.fingertip_contacts()
        J = p.fingertip_jacobians(contacts)
        c_measured = p.contact_intensities(contacts)
        qvel = p.hand_qvel()
        tips = p.tip_positions()
        state = env.state
        tip_x = state.tip_x
        noise = env.sensor_noise
        if noise is not None:  # the expert measures through the task's sensor noise
            touching = np.repeat(contacts.active, 3)
            c_measured = np.where(
                touching, noise.contact_intensities(c_measured, contacts.frames), 0.0
            )
            qvel = qvel + noise.qvel
            tips = tips + noise.tip_displacement(J, contacts.frames)
            tip_x = tip_x + (tips - p.tip_positions()) @ state.axis
        internal = None if internal_offsets is None else internal_offsets[i]
        task_offset = env.internal_force_reference()
        if task_offset is not None:
            internal = task_offset if internal is None else internal + task_offset
        offsets.append(internal)
        active = contacts.active
        # A skill's grasp margin (IAS-PenSkill-v0, docs/transfer.md), while every finger holds.
        margin_reference = getattr(env, "grasp_margin_reference", None)
        margins.append(
            float(margin_reference())
            if margin_reference is not None and bool(active.all())
            else None
        )
        slides.append({j: s for j, s in ref.sliding.items() if active[j]})
        sliding = np.zeros(k, dtype=bool)
        sliding[list(slides[-1])] = True
        scheduled = ref.contact_x is not None and ref.contact_vx is not None
        first = ctrl._prev_W is None or ctrl._prev_J is None
        rows.append(
            (
                state.vector[:12],
                np.stack(
                    (ref.position, ref.acceleration, ref.axis, ref.alpha, ref.velocity, ref.omega)
                ),
                ref.contact_x if scheduled else np.zeros(k),
                ref.contact_vx if scheduled else np.zeros(k),
                sliding,
                active,
                contacts.points,
                contacts.frames,
                p.pen_com(),
                J,
                np.zeros((6, 3 * k)) if first else ctrl._prev_W,
                np.zeros(J.shape) if first else ctrl._prev_J,
                c_measured,
                ctrl._extra,
                qvel,
                tips,
                tip_x,
                p.hand_forces(env.data.qfrc_bias - env.data.qfrc_gravcomp),
                ctrl._damping(env),
                p.pen_inertia(nominal=True),
                ctrl._g(env),
                env._ctrl_max,
                *((p.hand_mass_matrix(),) if g.finger_inertia else ()),
            )
        )
        scalars.append((p.pen_mass_nominal, env.config.control_dt, first, scheduled))
    x = Gathered().stack(rows, scalars)
    return _control_step(controllers, x, refs, slides, offsets, accel_offsets, margins)


def _control_step(
    controllers: Sequence[GripTransformController],
    x: Gathered,
    refs: Sequence[PenReference],
    slides: Sequence[dict[int, FloatArray]],
    offsets: Sequence[FloatArray | None],
    accel_offsets: FloatArray | None,
    margins: Sequence[float | None],
) -> FloatArray:
    """The control step of :func:`batch_torques` on the gathered rows (order of eq. 45)."""
    g = controllers[0].gains
    settings = controllers[0]._settings
    state = MotionRows(x.motion)
    ref = ReferenceRows(x.ref)
    active = x.active
    W = W_tips = wrench_matrices(x.points, x.frames, x.com)
    if not active.all():  # zero columns for fingers not touching
        W = np.where(np.repeat(active, 3, axis=-1)[:, None, :], W, 0.0)
    J = x.J

    a_d = law.object_acceleration(state, ref, kp=g.kp, kv=g.kv, kp_rot=g.kp_rot, kv_rot=g.kv_rot)
    if g.ki > 0:
        bound = g.integral_limit / g.ki
        error = ref.position - state.position
        for i, ctrl in enumerate(controllers):
            ctrl._integral = np.clip(ctrl._integral + error[i] * x.dt[i, 0], -bound, bound)
        a_d[:, :3] += g.ki * np.stack([ctrl._integral for ctrl in controllers])
    if accel_offsets is not None:
        a_d = a_d + accel_offsets
    mass, pen_inertia = x.mass, x.inertia
    if g.mass_time_constant > 0:
        current = [x.mass[i] if c._mass is None else c._mass for i, c in enumerate(controllers)]
        mass = estimated_masses(np.array(current, dtype=float), x, W, g.mass_time_constant)
        for ctrl, estimate in zip(controllers, mass, strict=True):
            ctrl._mass = float(estimate)
        pen_inertia = x.inertia * (mass / x.mass)[:, None, None]
    wrench = law.object_wrench(mass, pen_inertia, state.omega, a_d, x.gravity)
    c_ref = np.empty_like(x.c_measured)
    feasible = [True] * len(controllers)
    for i, ctrl in enumerate(controllers):
        assert ctrl._solver is not None and ctrl._last_c is not None
        try:
            c_ref[i] = ctrl._last_c = ctrl._solver.solve(W[i], -wrench[i], slides[i]).c
        except InfeasibleGraspError:
            ctrl.infeasible_count += 1
            c_ref[i] = ctrl._last_c
            feasible[i] = False

    # Grip transform of the measured W (eqs. 5, 7): c = c_p + c_h.
    W_pinv = right_inverses(W, active.sum(axis=-1))
    dW = (W - x.prev_W) / x.dt[:, :, None]
    first = bool(x.first.any())
    if first:
        dW[x.first] = 0.0
    c_p = law._matvec(W_pinv, wrench)
    c_h_d = law.internal_part(c_ref, W, W_pinv)
    # (not x.sliding, the schedule's sliding fingers: tips measured to slip over the pen)
    slipping = None
    senses = math.isfinite(g.slip_speed) or g.plateau_time > 0
    if senses and any(c._estimates_friction for c in controllers):
        slipping = slip_speeds(state, x) >= g.slip_speed
    for i, (ctrl, margin) in enumerate(zip(controllers, margins, strict=True)):
        if slipping is not None and ctrl._estimates_friction:
            ctrl._friction.update(x.c_measured[i], slipping[i], ctrl.f0, float(x.dt[i, 0]))
        if margin is not None:
            # The hand's own internal forces, scaled so that c_p + c_h^d has the margin.
            held = max(margin, g.margin_floor)
            c_h_d[i] = scale_to_margin(c_p[i], c_h_d[i], held, ctrl.friction)
            c_h_d[i] = resolvable_squeeze(
                c_p[i], c_h_d[i], g.friction_floor, J[i], x.frames[i], x.damping[i, 1], active[i]
            )
    offset_scale = [1.0] * len(controllers)
    for i, ctrl in enumerate(controllers):
        internal_offset = offsets[i]
        if internal_offset is not None and np.any(internal_offset):
            ctrl._N = null_space_basis(W[i], ctrl._N) if bool(active[i].all()) else ctrl._N
            if ctrl._N is not None:
                # A requested offset is taken only as far as the cones allow (a squeeze that
                # opens a contact or pushes one out of its cone would drop the object).
                offset = law.keep_sliding_friction(ctrl._N, internal_offset, slides[i], settings.mu)
                offset_scale[i] = law.largest_step_inside_cones(
                    c_p[i] + c_h_d[i], offset, active[i], slides[i], settings
                )
                c_h_d[i] = c_h_d[i] + offset_scale[i] * offset
    # The servo forces below (lateral, sliding) are part of what the contacts carry but not
    # of the grasp model's c; left in the measurement, eq. (44) would feed them back and
    # amplify them by 1 / (delta dt) (measured: at delta dt = 0.25 the grasp broke).
    c_model = x.c_measured - x.extra
    c_h = law.internal_part(c_model, W, W_pinv)
    e_f = c_h - c_h_d
    # One explicit-Euler step of eq. (44): e_f' = -(delta I + W+ W') e_f.
    step = law.internal_force_step(e_f, W_pinv, dW, g.delta, x.dt)
    c_feasible = c_p + c_h_d
    error_scale = law.largest_steps_inside_cones(c_feasible, step, active, x.sliding, settings)
    c_h_cmd = c_h_d + error_scale[:, None] * step
    c_cmd = c_p + c_h_cmd

    extra = np.zeros(c_cmd.shape)
    extra[:, 2::3] = lateral_servo(g.kp_lateral, g.kv_lateral, state, x.frames, J, x.qvel, x.tips)
    extra[:, 1::3] = slide_servo(g.kp_slide, g.kv_slide, state, x, J)
    f = c_cmd + extra

    # H of eq. (35): Coriolis/centrifugal forces (gravity is compensated by the model's
    # gravcomp). The joints' passive damping is deliberately NOT cancelled: sampled and
    # held for a control period, a cancellation turns into negative damping of the
    # grasp's roll mode (tips circling the pen, which rolls with them), which nothing else
    # damps; measured: the pen's roll rate doubled every 0.2 s and it fell after 1.2 s.
    inertia = feedforward = None
    if g.finger_inertia or g.damping_feedforward:
        J_pinv = law.damped_pinv_blocks(J, g.jacobian_damping)
        touching = np.repeat(active, 3, axis=-1)
    if g.finger_inertia:
        # J' over one control period; zero on the first step (no previous J).
        dJ = (J - x.prev_J) / x.dt[:, :, None]
        if first:
            dJ[x.first] = 0.0
        v = x.motion[:, 6:]  # [velocity; omega]
        inertia = law.finger_inertia_torques(x.M, J_pinv, W, dW, dJ, x.qvel, a_d, v, touching)
    if g.damping_feedforward:
        feedforward = damping_feedforward(g, x, state, ref, J_pinv, W_tips, touching)
    tau = with_motion(law.joint_torques(J, f, x.coriolis), (inertia, feedforward), x, g.hold_first)

    for i, ctrl in enumerate(controllers):
        ctrl._prev_W, ctrl._prev_J, ctrl._extra = W[i], J[i], extra[i]
        ctrl.last = ControlStep(
            tau[i],
            wrench[i],
            c_h_d[i],
            c_h[i],
            c_cmd[i],
            active[i].copy(),
            feasible[i],
            offset_scale[i],
            float(error_scale[i]),
        )
    return tau

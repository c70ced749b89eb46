"""The terms of Theorem 1 (paper sec. 3.3, eqs. 33, 41-45) as pure functions on arrays.

Each function is one term of the control law, named after its equation; none reads a
simulation (numpy and :mod:`ias_gym.grasp` only), so each can be checked on a synthetic grasp
(``tests/test_law.py``). :class:`~ias_gym.baselines.grip_transform_control.GripTransformController`
reads the physics and calls them in the order of eq. (45)::

    a_d    = object_acceleration(state, ref, ...)                  eqs. (41), (43)
    w      = object_wrench(m, I, omega, a_d, g)                    eq. (33) + weight (eq. 18)
    c_p    = W+ w,  c_h^d = internal part of the LP's solution      eqs. (5), (7), (19)-(24)
    step   = internal_force_step(e_f, W+, W', delta, dt)            eq. (44), one Euler step
    lam    = largest_step_inside_cones(c_p + c_h^d, step, ...)      (the cones, not the paper)
    f      = c_p + c_h^d + lam step (+ servo forces)
    tau    = joint_torques(J, f, H, finger_inertia_torques(...), damping_feedforward_torques(...))

Frames and units as the adapter's: the paper frame (x the pen's axis, y up), SI units;
intensities per contact ``[normal, t1, t2]`` [N]; ``J`` is block diagonal with one 3 x 3 block
per finger (eq. 35's ``diag(J_1 ... J_k)``).

Batches: every array argument may carry leading axes (``(..., 6, 3 k)`` for W, ``(..., 3)``
for a vector), one entry per env, and the result has them too: the adapter computes the law
for ``n`` envs in one call each (:func:`~ias_gym.baselines.grip_transform_control.
batch_torques`). The shapes in the docstrings are those of one env. The module docstring of
:mod:`~ias_gym.baselines.grip_transform_control` explains where the code departs from the paper
and why; docs/controller.md records the measurements.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from ias_gym.grasp.internal_forces import (
    POLYGON_DIRECTIONS,
    POLYGON_SCALE,
    InternalForceSettings,
)
from ias_gym.grasp.wrench_matrix import cross_last

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


class ObjectMotion(Protocol):
    """The measured object state the law needs (the env's ``PenState`` has it)."""

    @property
    def position(self) -> FloatArray:
        """Object centre [m] (3,)."""

    @property
    def velocity(self) -> FloatArray:
        """Object centre velocity [m/s] (3,)."""

    @property
    def axis(self) -> FloatArray:
        """Unit direction of the object's axis (3,) (its roll about it is free)."""

    @property
    def omega(self) -> FloatArray:
        """Angular velocity [rad/s] (3,)."""


class ObjectReference(ObjectMotion, Protocol):
    """The desired object trajectory of eqs. (25)-(28) (the env's ``PenReference`` has it)."""

    @property
    def acceleration(self) -> FloatArray:
        """Desired acceleration of the centre ``r''_d`` [m/s^2] (3,)."""

    @property
    def alpha(self) -> FloatArray:
        """Desired angular acceleration ``omega'_d`` [rad/s^2] (3,)."""


def object_acceleration(
    state: ObjectMotion,
    ref: ObjectReference,
    *,
    kp: float,
    kv: float,
    kp_rot: float,
    kv_rot: float,
) -> FloatArray:
    """Desired object acceleration ``a_d = [v'; omega']`` of eqs. (41), (43).

    PD with feed-forward: ``r''_d - Kv e_v - Kp e_p`` for the centre, and
    ``omega'_d + Kp_rot (axis x axis_d) - Kv_rot (omega_across - omega_d)`` for the orientation,
    whose error is taken on the axis (eq. 41 with ``Psi = I``), so the roll about the object's
    own axis is left free: only the part of ``omega`` across the axis is damped.

    Args:
        state: the measured object motion (paper frame) [m, m/s, -, rad/s].
        ref: the reference at this instant [m, m/s, m/s^2, -, rad/s, rad/s^2].
        kp: position stiffness Kp [1/s^2].
        kv: position damping Kv [1/s].
        kp_rot: orientation stiffness [1/s^2].
        kv_rot: orientation damping [1/s].

    Returns:
        ``(6,)`` ``[a (m/s^2); alpha (rad/s^2)]``.
    """
    omega, axis = state.omega, state.axis
    acc = ref.acceleration - kv * (state.velocity - ref.velocity) - kp * state.position
    acc += kp * ref.position
    omega_across = omega - _dot(omega, axis)[..., None] * axis
    alpha = ref.alpha + kp_rot * cross_last(axis, ref.axis) - kv_rot * (omega_across - ref.omega)
    return np.concatenate([acc, alpha], axis=-1)


def object_wrench(
    mass: float | FloatArray,
    inertia: FloatArray,
    omega: FloatArray,
    a_d: FloatArray,
    gravity: FloatArray,
) -> FloatArray:
    """Net contact wrench that gives the object the acceleration ``a_d``: eq. (33) plus weight.

    ``w = [m a; I alpha + omega x I omega] - [m g; 0]``: Newton-Euler solved for the wrench.
    The paper's eq. (33) has no gravity (its ``f_ext`` is the contact wrench); the weight of
    eq. (18) is added here, so that ``c_p = W+ w`` (eqs. 5, 36) holds the object up.

    Args:
        mass: object mass [kg] (``(n,)`` for a batch).
        inertia: ``(3, 3)`` inertia tensor about the centre of mass [kg m^2], same frame.
        omega: angular velocity [rad/s] (3,).
        a_d: ``(6,)`` desired acceleration ``[a; alpha]`` [m/s^2, rad/s^2].
        gravity: gravitational acceleration [m/s^2] (3,), e.g. ``(0, -9.81, 0)`` paper frame.

    Returns:
        ``(6,)`` ``[force (N); moment about the centre of mass (N m)]``.
    """
    mass = np.asarray(mass)[..., None]  # a batch of masses broadcasts over the force
    force = mass * a_d[..., :3] - mass * gravity
    moment = _matvec(inertia, a_d[..., 3:]) + cross_last(omega, _matvec(inertia, omega))
    return np.concatenate([force, moment], axis=-1)


def internal_part(c: FloatArray, W: FloatArray, W_pinv: FloatArray) -> FloatArray:
    """The internal (null-space) part ``c_h = c - W+ W c`` of intensities c (eqs. 4, 5, 7).

    Args:
        c: ``(n,)`` wrench intensities [N].
        W: ``(6, n)`` wrench matrix.
        W_pinv: ``(n, 6)`` its right inverse ``W+``.
    """
    result: FloatArray = c - _matvec(W_pinv, _matvec(W, c))
    return result


def internal_force_step(
    e_f: FloatArray, W_pinv: FloatArray, dW: FloatArray, delta: float, dt: float | FloatArray
) -> FloatArray:
    """The internal-force error one explicit-Euler step of eq. (44) ahead.

    Eq. (44) prescribes ``e_f' = -(delta I + W+ W') e_f``; one step of length ``dt`` gives
    ``e_f + dt e_f'``. With ``W' = 0`` that is ``(1 - delta dt) e_f``.

    Args:
        e_f: ``(n,)`` internal-force error ``c_h - c_h^d`` [N].
        W_pinv: ``(n, 6)`` right inverse ``W+`` of the wrench matrix.
        dW: ``(6, n)`` its rate ``W'`` [1/s, m/s].
        delta: the error's decay rate delta [1/s].
        dt: the control period [s] (``(n, 1)`` for a batch of envs).

    Returns:
        ``(n,)`` the error to command after one step [N].
    """
    result: FloatArray = e_f - dt * (delta * e_f + _matvec(W_pinv, _matvec(dW, e_f)))
    return result


def largest_step_inside_cones(
    c_ref: FloatArray,
    step: FloatArray,
    active: BoolArray,
    sliding: Collection[int],
    settings: InternalForceSettings,
) -> float:
    """The largest ``lam`` in [0, 1] that keeps ``c_ref + lam step`` in the solver's cones.

    The constraints are those of the internal-force problem (eqs. 19-24): for every active
    contact the normal force ``c_n >= f0``, and for every sticking (active, not sliding) one
    the friction faces ``|d . c_t| <= k mu (1 - margin) c_n`` (the box's two axes with
    ``k = 1``, or the polygon's four directions with ``k = cos(pi / 8)``; an ``"exact"`` cone
    is limited by its box). ``c_ref`` is feasible and the feasible set is convex, so the
    admissible ``lam`` form an interval from 0 that the first constraint ``step`` crosses
    ends. Not in the paper: eq. (44) lets the internal forces lag while ``c_p`` acts at once,
    and the sum could leave the cones during transients (docs/controller.md).
    :func:`largest_steps_inside_cones` is the same for a batch.

    Args:
        c_ref: ``(3 k,)`` feasible intensities ``c_p + c_h^d`` [N].
        step: ``(3 k,)`` the change to take [N].
        active: ``(k,)`` contacts that touch.
        sliding: indices of sliding contacts (only their normal bound applies).
        settings: the internal-force problem's ``mu``, ``f0`` [N], ``margin`` and ``cone``.

    Returns:
        ``lam`` [-], 1.0 when the whole step is feasible.
    """
    mask = np.zeros(len(active), dtype=bool)
    mask[list(sliding)] = True
    return float(largest_steps_inside_cones(c_ref, step, active, mask, settings))


def largest_steps_inside_cones(
    c_ref: FloatArray,
    step: FloatArray,
    active: BoolArray,
    sliding: BoolArray,
    settings: InternalForceSettings,
) -> FloatArray:
    """:func:`largest_step_inside_cones` for a batch: one ``lam`` per leading index.

    Args:
        c_ref: ``(..., 3 k)`` feasible intensities [N].
        step: ``(..., 3 k)`` the changes to take [N].
        active: ``(..., k)`` contacts that touch.
        sliding: ``(..., k)`` contacts that slide (only their normal bound applies).
        settings: the internal-force problem's settings.

    Returns:
        ``(...)`` ``lam`` [-] in [0, 1].
    """
    faces, scale = _cone_faces(settings.cone)
    k_mu = scale * settings.mu_sticking
    c = c_ref.reshape(*c_ref.shape[:-1], -1, 3)
    d = step.reshape(c.shape)
    # Rows a + lam b >= 0: n - f0, then k mu n -+ d . t for each face direction d
    # (the friction rows only for sticking contacts).
    a = _constraint_rows(c, faces, k_mu, settings.f0)
    b = _constraint_rows(d, faces, k_mu, 0.0)
    use = np.empty(a.shape, dtype=bool)
    use[..., 0] = active
    use[..., 1:] = (active & ~sliding)[..., None]
    crossing = use & (b < 0)
    if not crossing.any():
        return np.ones(a.shape[:-2])
    # Where a row is crossed its bound is max(a, 0) / -b (-b > 0); elsewhere inf.
    bounds = np.where(crossing, np.maximum(a, 0.0) / np.where(crossing, -b, 1.0), np.inf)
    result: FloatArray = np.minimum(1.0, bounds.reshape(*bounds.shape[:-2], -1).min(axis=-1))
    return result


def _cone_faces(cone: str) -> tuple[FloatArray, float]:
    """The face directions (F, 2) and their scale k of a cone (an exact one: its box)."""
    if cone == "polygon":
        return POLYGON_DIRECTIONS, POLYGON_SCALE
    return _BOX_DIRECTIONS, 1.0


_BOX_DIRECTIONS = np.eye(2)


def keep_sliding_friction(
    offset_basis: FloatArray, f: FloatArray, sliding: Mapping[int, FloatArray], mu: float
) -> FloatArray:
    """The internal-force offset ``N f`` with its part that breaks kinetic friction removed.

    A sliding contact's tangential force is its kinetic friction, ``c_t = mu c_n s``
    (docs/NOTES.md "Sliding contact"); an offset along an arbitrary internal direction would ask
    the sliding finger for a tangential force that friction cannot deliver, and the difference
    would push the object (measured: a slider 14 mm off its schedule under +-0.1 N steps). The
    offset is projected, in least squares, onto the directions that keep ``c_t - mu c_n s = 0``
    at every sliding contact.

    Args:
        offset_basis: ``(3 m, r)`` internal-force directions N (eq. 7).
        f: ``(r,)`` requested offset along them [N].
        sliding: {contact index: unit sliding direction s in (t1, t2)}.
        mu: kinetic friction coefficient [-].

    Returns:
        ``(3 m,)`` the offset ``N f'`` [N] that respects every sliding contact's friction.
    """
    if not sliding:
        result: FloatArray = offset_basis @ f
        return result
    rows = []
    for k, s in sliding.items():
        for axis in (0, 1):  # c_t[axis] - mu s[axis] c_n = 0
            row = np.zeros(offset_basis.shape[0])
            row[3 * k] = -mu * s[axis]
            row[3 * k + 1 + axis] = 1.0
            rows.append(row)
    A = np.array(rows) @ offset_basis
    kept = f - np.linalg.pinv(A) @ (A @ f)
    result = offset_basis @ kept
    return result


def _constraint_rows(c: FloatArray, faces: FloatArray, k_mu: float, f0: float) -> FloatArray:
    """``(..., k, 1 + 2 F)`` per contact: ``c_n - f0``, then ``k mu c_n - d . c_t`` and
    ``k mu c_n + d . c_t`` for the F face directions d (``>= 0``: inside)."""
    normal, along = c[..., :1], c[..., 1:] @ faces.T
    friction = k_mu * normal
    result: FloatArray = np.concatenate([normal - f0, friction - along, friction + along], axis=-1)
    return result


def damped_pinv_blocks(J: FloatArray, damping: float) -> FloatArray:
    """The diagonal blocks of ``J+ = J^T (J J^T + damping I)^-1`` (eq. 32), ``(k, 3, 3)``.

    J is block diagonal, one 3 x 3 block per finger (eq. 35's ``diag(J_1 ... J_k)``), so J+
    is too; the blocks of every finger (and env) are inverted in one batched call (damped
    near singular fingers).

    Args:
        J: ``(..., 3 k, 3 k)`` block-diagonal fingertip Jacobian [m/rad].
        damping: damping of the inverse [m^2]; 0 gives the exact inverse of each block.

    Returns:
        ``(..., k, 3, 3)`` the blocks of J+ [rad/m].
    """
    k = J.shape[-1] // 3
    # (m, 3, 3, k) diagonal blocks of the m Jacobians -> (..., k, 3, 3): [finger, row, col]
    diagonal = np.diagonal(J.reshape(-1, k, 3, k, 3), axis1=1, axis2=3)
    blocks = diagonal.transpose(0, 3, 1, 2).reshape(*J.shape[:-2], k, 3, 3)
    blocks_t = blocks.swapaxes(-1, -2)
    result: FloatArray = blocks_t @ np.linalg.inv(blocks @ blocks_t + damping * np.eye(3))
    return result


def apply_blocks(blocks: FloatArray, x: FloatArray) -> FloatArray:
    """``blockdiag(blocks) @ x`` for ``(..., k, 3, 3)`` blocks and ``(..., 3 k)`` x."""
    xs = x.reshape(*x.shape[:-1], -1, 3)
    result: FloatArray = np.einsum("...kij,...kj->...ki", blocks, xs).reshape(x.shape)
    return result


def finger_inertia_torques(
    M: FloatArray,
    J_pinv_blocks: FloatArray,
    W: FloatArray,
    dW: FloatArray,
    dJ: FloatArray,
    qvel: FloatArray,
    a_d: FloatArray,
    v: FloatArray,
    touching: BoolArray,
) -> FloatArray:
    """``M J+ (W^T a_d + W'^T v - J' theta')``: eqs. (32), (39), (45) with ``v_int = 0``.

    The joint torques that give the fingers the accelerations keeping the contact points
    moving with the object (the second half of eq. 39's ``M* a_d`` and eq. 45's
    ``M J+ {...}``); the rows of fingers that do not touch are left out.

    Args:
        M: ``(n, n)`` joint-space inertia [kg m^2].
        J_pinv_blocks: ``(k, 3, 3)`` blocks of ``J+`` (:func:`damped_pinv_blocks`) [rad/m].
        W: ``(6, 3 k)`` wrench matrix.
        dW: ``(6, 3 k)`` its rate ``W'``.
        dJ: ``(3 k, n)`` the Jacobian's rate ``J'`` [m/(rad s)].
        qvel: ``(n,)`` joint velocities ``theta'`` [rad/s].
        a_d: ``(6,)`` desired object acceleration [m/s^2, rad/s^2].
        v: ``(6,)`` object twist ``[v; omega]`` [m/s, rad/s].
        touching: ``(3 k,)`` rows of touching fingers.

    Returns:
        ``(n,)`` joint torques [N m].
    """
    contact_acc = _matvec_t(W, a_d) + _matvec_t(dW, v) - _matvec(dJ, qvel)
    contact_acc[~touching] = 0.0
    result: FloatArray = _matvec(M, apply_blocks(J_pinv_blocks, contact_acc))
    return result


def damping_feedforward_torques(
    damping: FloatArray,
    J_pinv_blocks: FloatArray,
    W: FloatArray,
    v_ref: FloatArray,
    touching: BoolArray,
) -> FloatArray:
    """The joints' damping along the reference motion, ``D J+ W^T v_d`` (beyond the paper).

    Fingers that follow the object drag on it through their joints' damping; this cancels
    that drag along the *reference* twist, never the measured one (docs/controller.md).

    Args:
        damping: ``(n,)`` joint damping coefficients [N m s/rad].
        J_pinv_blocks: ``(k, 3, 3)`` blocks of ``J+`` [rad/m].
        W: ``(6, 3 k)`` wrench matrix.
        v_ref: ``(6,)`` reference twist ``[v_d; omega_d]`` [m/s, rad/s].
        touching: ``(3 k,)`` rows of touching fingers.

    Returns:
        ``(n,)`` joint torques [N m].
    """
    qvel_ref = apply_blocks(J_pinv_blocks, np.where(touching, _matvec_t(W, v_ref), 0.0))
    result: FloatArray = damping * qvel_ref
    return result


def coulomb_feedforward_torques(
    coulomb: FloatArray,
    J_pinv_blocks: FloatArray,
    W: FloatArray,
    v_d: FloatArray,
    touching: BoolArray,
    speed: float,
) -> FloatArray:
    """The joints' Coulomb friction along a desired object twist, ``F tanh(q'_d / speed)``
    with ``q'_d = J+ W^T v_d`` (beyond the paper).

    A joint with dry friction ``F`` (MuJoCo's ``frictionloss``) sticks until its torque
    exceeds ``F``; the feed-forward pays it in the direction the fingers are to move (its
    sign made smooth by ``tanh`` where the motion reverses). ``v_d`` is the reference twist
    plus the error's own correction (the controller's), so that a small tracking error is
    corrected too instead of stuck.

    Args:
        coulomb: ``(n,)`` the joints' Coulomb friction [N m].
        J_pinv_blocks: ``(k, 3, 3)`` blocks of ``J+`` [rad/m].
        W: ``(6, 3 k)`` wrench matrix.
        v_d: ``(6,)`` the desired twist ``[v; omega]`` [m/s, rad/s].
        touching: ``(3 k,)`` rows of touching fingers.
        speed: the joint speed at which the feed-forward reaches ``tanh(1)`` of ``F``
            [rad/s].

    Returns:
        ``(n,)`` joint torques [N m].
    """
    qvel = apply_blocks(J_pinv_blocks, np.where(touching, _matvec_t(W, v_d), 0.0))
    result: FloatArray = coulomb * np.tanh(qvel / speed)
    return result


def joint_torques(
    J: FloatArray,
    f: FloatArray,
    H: FloatArray,
    finger_inertia: FloatArray | None = None,
    damping_feedforward: FloatArray | None = None,
) -> FloatArray:
    """Eq. (45): ``tau = J^T f + H + M J+ {...}`` (+ the damping feed-forward).

    Args:
        J: ``(3 k, n)`` fingertip Jacobian [m/rad].
        f: ``(3 k,)`` contact forces to command, ``c_p + c_h_cmd`` plus servo forces [N].
        H: ``(n,)`` bias torques of eq. (35) [N m].
        finger_inertia: ``(n,)`` :func:`finger_inertia_torques` [N m], ``None``: left out.
        damping_feedforward: ``(n,)`` :func:`damping_feedforward_torques` [N m], ``None``:
            left out.

    Returns:
        ``(n,)`` joint torques [N m].
    """
    tau: FloatArray = _matvec_t(J, f) + H
    if finger_inertia is not None:
        tau += finger_inertia
    if damping_feedforward is not None:
        tau += damping_feedforward
    return tau


def _dot(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a . b`` along the last axis, ``(...)``: numpy's dot product per row (the bits of
    ``a[i] @ b[i]``; an elementwise sum rounds differently)."""
    if a.ndim == 1:
        return np.asarray(a @ b)
    if a.ndim == 2 and len(a) == 1:
        return np.asarray(a[0] @ b[0])[None]
    result: FloatArray = (a[..., None, :] @ b[..., :, None])[..., 0, 0]
    return result


def _matvec(A: FloatArray, x: FloatArray) -> FloatArray:
    """``A x`` for ``(..., m, n)`` A and ``(..., n)`` x (a batch of matrix-vector products).

    A batch of one takes numpy's 2-D product (a third of the time, the same bits: numpy
    multiplies each matrix of a stack as it does a single one).
    """
    if A.ndim == 2 or (A.ndim == 3 and len(A) == 1):
        result: FloatArray = (A[0] @ x[0])[None] if A.ndim == 3 else A @ x
        return result
    result = (A @ x[..., None])[..., 0]
    return result


def _matvec_t(A: FloatArray, x: FloatArray) -> FloatArray:
    """``A^T x`` for ``(..., m, n)`` A and ``(..., m)`` x (as :func:`_matvec`)."""
    if A.ndim == 2 or (A.ndim == 3 and len(A) == 1):
        result: FloatArray = (x[0] @ A[0])[None] if A.ndim == 3 else x @ A
        return result
    result = (x[..., None, :] @ A)[..., 0, :]
    return result

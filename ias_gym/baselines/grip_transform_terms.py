"""The batched terms of the grip-transform controller: gathered rows, servos, inverses.

:func:`~ias_gym.baselines.grip_transform_control.batch_torques` reads ``n`` envs into one
:class:`Gathered` (a row per env, paper frame) and computes the control step on the rows;
the pieces it needs beyond the law's pure terms (:mod:`ias_gym.baselines.law`) live here:
what a step computed (:class:`ControlStep`), the reference extrapolated by the controller's
lead (:func:`ahead`), the rows as the law's motion and reference (:class:`MotionRows`,
:class:`ReferenceRows`), the batched right inverse ``W+`` of eq. (5) (:func:`right_inverses`),
the two servos beyond the paper that hold the tips on the pen (:func:`lateral_servo`) and
move sliding tips along their schedule (:func:`slide_servo`), the estimate of the pen's
mass (:func:`estimated_masses`), the motion terms added within the motors' limits
(:func:`with_motion`, :func:`motion_share`), the joints' damping and Coulomb feed-forward
(:func:`damping_feedforward`) and the least squeeze a finger with sticking joints can set
(:func:`force_resolution`, :func:`resolvable_squeeze`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ias_gym.baselines import law
from ias_gym.baselines.gains import ControllerGains
from ias_gym.envs.pen_hand_env import FloatArray, PenReference
from ias_gym.grasp.grip_transform import pseudo_inverse
from ias_gym.grasp.wrench_matrix import cross3

NDArrayBool = np.ndarray


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


def ahead(ref: PenReference, lead: float) -> PenReference:
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


class Gathered:
    """What :func:`~ias_gym.baselines.grip_transform_control.batch_torques` reads from ``n``
    envs: one row per env (paper frame).

    Each env's values are collected in lists and stacked once per field (a batch of one
    takes a view of its only row: no copy).
    """

    motion: FloatArray  # (n, 12) measured position, axis, velocity, omega
    ref: FloatArray  # (n, 6, 3) reference position, acceleration, axis, alpha, velocity, omega
    contact_x: FloatArray  # (n, k) sliding schedule [m] (0: none)
    contact_vx: FloatArray  # (n, k) [m/s]
    sliding: NDArrayBool  # (n, k) touching and sliding
    active: NDArrayBool  # (n, k)
    points: FloatArray  # (n, k, 3)
    frames: FloatArray  # (n, k, 3, 3)
    com: FloatArray  # (n, 3)
    J: FloatArray  # (n, 3 k, dofs)
    prev_W: FloatArray  # (n, 6, 3 k), zeros on a first step
    prev_J: FloatArray  # (n, 3 k, dofs)
    c_measured: FloatArray  # (n, 3 k)
    extra: FloatArray  # (n, 3 k) servo forces of the last step
    qvel: FloatArray  # (n, dofs)
    tips: FloatArray  # (n, k, 3)
    tip_x: FloatArray  # (n, k)
    M: FloatArray  # (n, dofs, dofs) (only with finger_inertia)
    limits: FloatArray  # (n, dofs) the motors' torque limits [N m]
    coriolis: FloatArray  # (n, dofs)
    damping: FloatArray  # (n, 2, dofs) viscous [N m s/rad] and Coulomb [N m]
    inertia: FloatArray  # (n, 3, 3)
    gravity: FloatArray  # (n, 3)
    mass: FloatArray  # (n,)
    dt: FloatArray  # (n, 1)
    scheduled: NDArrayBool  # (n, 1) the reference has a sliding schedule
    first: NDArrayBool  # (n,) no previous W and J (first step)

    #: The array fields, in the order of the rows :meth:`stack` takes.
    FIELDS = (
        "motion",
        "ref",
        "contact_x",
        "contact_vx",
        "sliding",
        "active",
        "points",
        "frames",
        "com",
        "J",
        "prev_W",
        "prev_J",
        "c_measured",
        "extra",
        "qvel",
        "tips",
        "tip_x",
        "coriolis",
        "damping",
        "inertia",
        "gravity",
        "limits",
        "M",
    )

    def stack(self, rows: list[tuple[Any, ...]], scalars: list[tuple[Any, ...]]) -> Gathered:
        """The fields from one row per env (arrays in the order of :attr:`FIELDS`) and the
        scalars ``(mass, dt, first, scheduled)`` per env."""
        if len(rows) == 1:
            for name, value in zip(self.FIELDS, rows[0], strict=False):
                setattr(self, name, value[None])
        else:
            for name, column in zip(self.FIELDS, zip(*rows, strict=True), strict=False):
                setattr(self, name, np.stack(column))
        mass, dt, first, scheduled = zip(*scalars, strict=True)
        self.mass, self.first = np.array(mass), np.array(first)
        self.dt, self.scheduled = np.array(dt)[:, None], np.array(scheduled)[:, None]
        return self


class MotionRows:
    """Rows of measured object motion (``law.ObjectMotion`` for a batch)."""

    def __init__(self, rows: FloatArray) -> None:
        self.position, self.axis = rows[:, 0:3], rows[:, 3:6]
        self.velocity, self.omega = rows[:, 6:9], rows[:, 9:12]
        self.twist = rows[:, 6:12]  # [velocity; omega]


class ReferenceRows:
    """Rows of references (``law.ObjectReference`` for a batch)."""

    def __init__(self, rows: FloatArray) -> None:
        self.position, self.acceleration, self.axis = rows[:, 0], rows[:, 1], rows[:, 2]
        self.alpha, self.velocity, self.omega = rows[:, 3], rows[:, 4], rows[:, 5]
        self.twist = rows[:, 4:].reshape(len(rows), 6)  # [velocity; omega]


def right_inverses(W: FloatArray, touching: np.ndarray | None = None) -> FloatArray:
    """``W+ = W^T (W W^T)^-1`` (eq. 5) of each ``(6, 3 k)`` W of a batch of hard-finger
    grasps (columns of a finger not touching are zero): one batched inverse of the 6 x 6
    ``W W^T`` (a solve with W's 3 k columns as right-hand sides costs the same and changes
    the last bits).

    A grasp with at most two touching contacts has rank W <= 5 (no moment about the line
    through them), so ``W W^T`` is singular: that env gets the least-squares inverse
    ``np.linalg.pinv(W)`` (:func:`~ias_gym.grasp.grip_transform.pseudo_inverse`), decided
    from the zero columns, not from the rounding errors of an elimination. So does every env
    of a batch whose inverse LAPACK finds singular.
    """
    if touching is None:  # the touching contacts: those with a nonzero column
        m = W.shape[-1] // 3
        touching = np.any(W.reshape(*W.shape[:-1], m, 3) != 0.0, axis=(-3, -1)).sum(axis=-1)
    few = touching <= 2
    if few.any():
        result = np.empty(W.swapaxes(-1, -2).shape)
        result[few] = [np.linalg.pinv(w) for w in W[few]]
        if (~few).any():
            result[~few] = right_inverses(W[~few], touching[~few])
        return result
    gram = W @ W.swapaxes(-1, -2)
    try:
        inverse: FloatArray = np.linalg.inv(gram).astype(np.float64, copy=False)
    except np.linalg.LinAlgError:
        return np.stack([pseudo_inverse(w, least_squares_if_singular=True) for w in W])
    result = W.swapaxes(-1, -2) @ inverse
    return result


def lateral_servo(
    kp: float,
    kv: float,
    s: MotionRows,
    frames: FloatArray,
    J: FloatArray,
    qvel: FloatArray,
    tips: FloatArray,
) -> FloatArray:
    """Forces along t2 [N] ``(n, k)`` that keep each tip on the pen's top or bottom line.

    Without them nothing holds the tips from circling the pen (the pen rolls with them at
    no cost), and they drift until the grasp breaks. The lateral direction is built from
    the vertical and the pen's axis, never from the pen's own (rolling) frame.
    """
    ax, az = s.axis[:, 0], s.axis[:, 2]
    norm = np.hypot(ax, az)
    lateral = np.zeros_like(s.axis)  # up x axis, normalised
    lateral[:, 0], lateral[:, 2] = az / norm, -ax / norm
    sign = law._matvec(frames[:, :, 2], lateral)  # t2 is +-lateral
    offset = law._matvec(tips - s.position[:, None], lateral)
    rate = sign * law._matvec(J[:, 2::3], qvel) - law._dot(s.velocity, lateral)[:, None]
    result: FloatArray = -sign * (kp * offset + kv * rate)
    return result


def slide_servo(kp: float, kv: float, s: MotionRows, x: Gathered, J: FloatArray) -> FloatArray:
    """Forces along t1 [N] ``(n, k)`` that move sliding tips along their schedule (eq. 17);
    zero for the others."""
    # Velocity of each tip along the pen relative to the pen's centre, from J.
    vx = law._matvec(J[:, 1::3], x.qvel) - law._dot(s.velocity, s.axis)[:, None]
    error = x.contact_x - x.tip_x
    force = kp * error + kv * (x.contact_vx - vx)
    result: FloatArray = np.where(x.sliding & x.scheduled, force, 0.0)
    return result


def slip_speeds(s: MotionRows, x: Gathered) -> FloatArray:
    """``(n, k)`` the speed [m/s] at which each tip slides over the pen at its contact: the
    tangential part of the tip's velocity (``J theta'``, contact frame) less the pen's at
    that point (``v + omega x (p - com)``); 0 for a tip that rolls or sticks, or is off."""
    tip = law._matvec(x.J, x.qvel).reshape(x.points.shape)
    lever = x.points - x.com[:, None]
    pen = s.velocity[:, None] + np.cross(s.omega[:, None], lever)
    relative = tip - np.einsum("nkij,nkj->nki", x.frames, pen)
    speed: FloatArray = np.where(x.active, np.hypot(relative[..., 1], relative[..., 2]), 0.0)
    return speed


#: The mass estimate stays within this range of the nominal mass [-] (a misread force
#: while a finger lands must not ask for a grip the hand cannot give).
MASS_ESTIMATE_RANGE = (0.5, 2.0)


def estimated_masses(current: FloatArray, x: Gathered, W: FloatArray, tau: float) -> FloatArray:
    """The estimates of the pen's mass [kg] ``(n,)``, updated from this step's measured tip
    forces: the net contact force ``W c`` holds the pen against gravity, so its component
    along ``-g`` over ``|g|^2`` is the mass (quasi-static), low-pass filtered with time
    constant ``tau`` [s] and kept within :data:`MASS_ESTIMATE_RANGE` of the nominal mass
    (``x.mass``). An env whose fingers do not all touch keeps its ``current`` estimate.
    """
    out = np.array(current, dtype=float)
    for i in range(len(out)):
        if bool(x.active[i].all()):
            force = (W[i] @ x.c_measured[i])[:3]
            gravity = x.gravity[i]
            low, high = (r * float(x.mass[i]) for r in MASS_ESTIMATE_RANGE)
            reading = float(np.clip(-(force @ gravity) / (gravity @ gravity), low, high))
            alpha = float(x.dt[i, 0]) / (tau + float(x.dt[i, 0]))
            out[i] += alpha * (reading - out[i])
    return out


def motion_share(hold: FloatArray, motion: FloatArray, limits: FloatArray) -> FloatArray:
    """The largest share ``s`` in [0, 1] of the motion terms that the motors can add (beyond
    the paper, which has no torque limits).

    ``|hold + s motion| <= limits`` on every joint whose holding torque is within its limit
    (a joint the holding torque saturates is clipped whatever ``s`` is). One ``s`` for all
    joints of an env: the fingers slow down together, so that they keep moving the object as
    one body, while the contact forces that hold it are kept whole. Clipping each joint's
    sum instead changes the force its tip presses with (measured on the LEAP hand: the
    abduction motors saturated by the damping feed-forward, the thumb lost the pen).

    Args:
        hold: ``(..., n)`` holding torques ``J^T f + H`` [N m].
        motion: ``(..., n)`` motion terms (finger inertia, damping feed-forward) [N m].
        limits: ``(..., n)`` the motors' torque limits [N m], > 0.

    Returns:
        ``(...)`` ``s`` [-].
    """
    free = (np.abs(hold) <= limits) & (motion != 0.0)
    room = limits - np.sign(motion) * hold  # >= 0 on the free joints
    bounds = np.where(free, room / np.where(free, np.abs(motion), 1.0), np.inf)
    result: FloatArray = np.minimum(1.0, bounds.min(axis=-1))
    return result


def with_motion(
    hold: FloatArray,
    motion: tuple[FloatArray | None, ...],
    x: Gathered,
    hold_first: bool,
) -> FloatArray:
    """``hold`` plus the motion terms that are not ``None``, in their order; with
    ``hold_first`` scaled by :func:`motion_share` of the motors' limits ``x.limits`` (1.0,
    eq. (45)'s torques to the bit, where no motor saturates). ``hold`` is changed in place.
    """
    terms = [term for term in motion if term is not None]
    if terms and hold_first:
        share = motion_share(hold, sum(terms[1:], terms[0]), x.limits)[:, None]
        terms = [share * term for term in terms]
    for term in terms:
        hold += term
    return hold


def force_resolution(J: FloatArray, frames: FloatArray, coulomb: FloatArray) -> FloatArray:
    """``(k,)`` per finger, the least normal force [N] at its contact that turns one of its
    joints past that joint's dry friction: ``min_j F_j / |(J_i^T n_i)_j|`` over the joints
    the force loads (beyond the paper). Below it every joint of the finger sticks, so the
    finger cannot set a normal force that small; 0 for a hand without joint friction.

    Args:
        J: ``(3 k, dofs)`` the fingertips' Jacobians.
        frames: ``(k, 3, 3)`` the contact frames, the normal first.
        coulomb: ``(dofs,)`` the joints' Coulomb friction [N m].
    """
    k = frames.shape[0]
    out = np.zeros(k)
    if not np.any(coulomb > 0):
        return out
    for i in range(k):
        lever = np.abs(frames[i, 0] @ J[3 * i : 3 * i + 3])  # torque per newton, each joint
        loaded = (lever > 1e-9) & (coulomb > 0)
        if loaded.any():
            out[i] = float(np.min(coulomb[loaded] / lever[loaded]))
    return out


def resolvable_squeeze(
    c_p: FloatArray,
    c_h: FloatArray,
    share: float,
    J: FloatArray,
    frames: FloatArray,
    coulomb: FloatArray,
    active: NDArrayBool,
) -> FloatArray:
    """``c_h`` scaled up (never down) so that each touching finger's normal intensity in
    ``c_p + c_h`` is at least ``share`` of its :func:`force_resolution`, where ``c_h`` presses
    that finger: a squeeze the finger can set with its joints' dry friction (beyond the
    paper; ``c_h`` itself for ``share`` 0 or a hand without joint friction).

    Args:
        c_p, c_h: ``(3 k,)`` particular and internal intensities [N] (normal first).
        share: ``ControllerGains.friction_floor`` [-].
        J, frames, coulomb: as :func:`force_resolution`.
        active: ``(k,)`` fingers in contact.
    """
    if share <= 0 or not np.any(coulomb > 0):
        return c_h
    floor = share * force_resolution(J, frames, coulomb)
    n_p, n_h = c_p[0::3], c_h[0::3]
    short = active & (n_h > 1e-9) & (n_p + n_h < floor)
    if not short.any():
        return c_h
    scale = float(np.max((floor[short] - n_p[short]) / n_h[short]))
    return c_h * max(scale, 1.0)


def damping_feedforward(
    g: ControllerGains,
    x: Gathered,
    state: MotionRows,
    ref: ReferenceRows,
    J_pinv: FloatArray,
    W: FloatArray,
    touching: NDArrayBool,
) -> FloatArray:
    """The joints' damping along the *reference* motion, and their Coulomb friction along it
    plus the error's correction (beyond the paper; ``g``: the controller's gains); for the
    fingers off the pen, :func:`approach_torques`. ``W`` holds the
    columns of every finger (those off the pen too).

    Never along the measured motion, which would cancel the damping (see
    :meth:`~ias_gym.baselines.grip_transform_control.GripTransformController.torques`):
    fingers that follow the object drag on it otherwise (measured: a 23 ms lag of the pen's
    tilt behind its reference).
    """
    v_ref = ref.twist
    out: FloatArray = law.damping_feedforward_torques(x.damping[:, 0], J_pinv, W, v_ref, touching)
    if g.coulomb_speed > 0 and np.any(x.damping[:, 1]):
        e_p, e_r = ref.position - state.position, np.cross(state.axis, ref.axis)
        v_d = v_ref + np.concatenate([g.kp / g.kv * e_p, g.kp_rot / g.kv_rot * e_r], -1)
        out = out + law.coulomb_feedforward_torques(
            x.damping[:, 1], J_pinv, W, v_d, touching, g.coulomb_speed
        )
    if g.approach_speed > 0 and not touching.all():
        out = out + approach_torques(
            x.damping[:, 0],
            x.damping[:, 1],
            J_pinv,
            W,
            state.twist,
            ~touching,
            g.approach_speed,
            g.coulomb_speed,
        )
    return out


def approach_torques(
    damping: FloatArray,
    coulomb: FloatArray,
    J_pinv_blocks: FloatArray,
    W: FloatArray,
    twist: FloatArray,
    off: NDArrayBool,
    approach_speed: float,
    coulomb_speed: float,
) -> FloatArray:
    """The joints' damping and Coulomb friction of fingers off the object, paid along the
    object's measured motion at their tips plus ``approach_speed`` toward it (beyond the
    paper).

    A finger whose contact opened gets the small force the internal-force problem gives it,
    which its joints' damping turns into a crawl (the LEAP hand's thumb: 0.1 N, 0.3 mm/s)
    while the object moves on; paid like this, the tip follows the object and closes the gap
    at ``approach_speed``. Along the measured motion, unlike
    :func:`~ias_gym.baselines.law.damping_feedforward_torques`: a finger off the object
    cannot drag on it.

    Args:
        damping, coulomb: ``(n,)`` the joints' damping [N m s/rad] and dry friction [N m].
        J_pinv_blocks: ``(k, 3, 3)`` blocks of ``J+`` [rad/m].
        W: ``(6, 3 k)`` wrench matrix with the columns of the fingers off the object (their
            tips' points and frames, the normal toward the object's axis).
        twist: ``(6,)`` the object's measured twist ``[v; omega]`` [m/s, rad/s].
        off: ``(3 k,)`` rows of the fingers off the object.
        approach_speed: the tips' closing speed along their normals [m/s].
        coulomb_speed: the joint speed of ``tanh(1)`` of the dry friction [rad/s] (0: none).

    Returns:
        ``(n,)`` joint torques [N m].
    """
    v_tips = law._matvec_t(W, twist)
    v_tips[..., 0::3] += approach_speed
    qvel = law.apply_blocks(J_pinv_blocks, np.where(off, v_tips, 0.0))
    result: FloatArray = damping * qvel
    if coulomb_speed > 0:
        result = result + coulomb * np.tanh(qvel / coulomb_speed)
    return result

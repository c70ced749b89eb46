"""The soft-finger contact model of the glove scene's pinch: its contacts and its math.

:class:`FingerContacts` is each finger's pen contacts resolved as one *soft-finger* contact
(a point contact with friction plus a torsion about its normal; four wrench intensities:
normal, t1, t2 [N], torsion [N m]), as
:meth:`~ias_gym.sim.glove_contacts.GlovePenPhysics.finger_contacts` resolves MuJoCo's
contacts (:mod:`ias_gym.sim.glove_contacts`). The functions here are the model's math on
those contacts, MuJoCo not needed: where a finger's net wrench is a force plus a torsion
(:func:`soft_contact_points`), W and c (:func:`soft_wrench_matrix`,
:func:`soft_contact_intensities`), the friction cone (:func:`soft_finger_cone_margin`) and
the pinch's internal forces (:func:`pinch_null_basis`, :func:`squeeze_null_vector`).

W (:func:`soft_wrench_matrix`, eq. 16 with the torsion column ``[0; n]`` per finger) is
then 6 x 8 for the two fingers and ``W c`` is the fingers' net wrench on the pen exactly,
force and moment (to 2e-17 N m; the hard-finger W of earlier versions, 6 x 6, missed the
moment by up to 1.8e-3 N m). While both fingers touch, rank W = 6: the torsions make the
moment about the line between the contacts that two point contacts cannot, so the grip
transform G (eq. 8) exists, with two internal forces, the squeeze and the opposed torsions
(:func:`pinch_null_basis`). :func:`soft_finger_cone_margin` checks MuJoCo's elliptic
condim-4 cone ``c_n >= sqrt((c_t1/mu)^2 + (c_t2/mu)^2 + (c_tau/mu_tau)^2)``: it holds
to rounding for every MuJoCo contact and for a finger resolved from one contact (a finger
resolved from several, e.g. pad and distal phalanx with different friction, is the sum
of several cones, not one).

Frames and origin as :mod:`ias_gym.sim.glove_contacts`: paper frame, positions relative to
the pen's nominal centre, SI units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ias_gym.grasp.grip_transform import RANK_RTOL
from ias_gym.grasp.wrench_matrix import ContactModel, wrench_matrix
from ias_gym.sim.contacts import PointContacts, cross

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Rank of W for two point contacts with friction at distinct points: the moment about the
#: line through them cannot be produced (eq. 3), and the null space is the squeeze (eq. 6).
PINCH_RANK = 5
#: Wrench intensities per finger of the soft-finger model: normal, t1, t2, torsion.
SOFT_COLUMNS = ContactModel.SOFT_FINGER.n_wrenches
#: Largest move of a finger's point from its centre of pressure to make its wrench a soft
#: finger's [m] (:func:`soft_contact_points`): half the pads' 6-7 mm radius (measured
#: moves: at most 1.3 mm over 2827 finger samples of four skill episodes).
MAX_POINT_SHIFT = 0.003


@dataclass(frozen=True)
class FingerContacts(PointContacts):
    """Each finger's pen contacts resolved as one soft-finger contact (paper frame).

    Attributes:
        active: ``(k,)`` bool, some geom of finger i touches the pen.
        points: ``(k, 3)`` the soft finger's point [m] (origin: nominal pen centre; see
            :func:`soft_contact_points`); the finger's tip site for a finger not touching.
        frames: ``(k, 3, 3)`` rows normal (the finger pushes along it), t1, t2; for a finger
            not touching, the normal points from the tip site to the pen's axis.
        force: ``(k, 3)`` summed force of finger i on the pen [N] (zero when not touching).
        moment: ``(k, 3)`` exact moment of finger i's contacts about the pen's centre of
            mass [N m], the pads' torsion included.
        count: ``(k,)`` number of MuJoCo contacts summed per finger.
        torsion: ``(k,)`` the soft finger's torsion [N m]: finger i's moment about its
            point, along its normal (0 when not touching).
        friction: ``(k, 2)`` the friction of finger i's contact (of its strongest MuJoCo
            contact): sliding mu [-] and torsional mu [m] (MuJoCo's condim-4 coefficients;
            the pad geoms' for a finger not touching).
    """

    moment: FloatArray
    count: NDArray[np.int64]
    torsion: FloatArray
    friction: FloatArray


def soft_contact_points(
    points: FloatArray,
    normals: FloatArray,
    force: FloatArray,
    moment: FloatArray,
    com: FloatArray,
    active: BoolArray,
) -> FloatArray:
    """Each finger's point as a soft finger: where its net wrench is a force plus a torsion.

    A finger's force ``F`` and moment ``M`` about ``com`` [N, N m] are one soft-finger
    contact at a point ``p`` with normal ``n`` exactly if the moment about ``p`` lies along
    ``n``: ``M - (p - com) x F = tau n``. Dotting with F gives ``tau = (M . F) / (n . F)``;
    the points that satisfy it form a line parallel to F, and the one nearest the centre of
    pressure is used. Where the finger has one MuJoCo contact this is its point (its moment
    about it is MuJoCo's torsion along the normal). The line moves by the tangential moment
    / |F| (several contacts of the finger, e.g. pad and distal phalanx), measured up to
    1.3 mm; a finger whose shift would exceed :data:`MAX_POINT_SHIFT`
    (a grazing contact, n . F near 0) keeps its centre of pressure.

    Args:
        points, normals, force, moment: ``(k, 3)`` per finger, MuJoCo's frame: centre of
            pressure [m], unit normal, net force [N], net moment about ``com`` [N m].
        com: ``(3,)`` the pen's centre of mass [m].
        active: ``(k,)`` the finger touches (others are returned unchanged).

    Returns:
        ``(k, 3)`` the points [m].
    """
    out = points.copy()
    for i in np.flatnonzero(active):
        F, M, n = force[i], moment[i], normals[i]
        ff, fn = float(F @ F), float(n @ F)
        if ff <= 0.0 or fn <= 1e-9:
            continue
        tangential = M - (float(M @ F) / fn) * n  # = r x F for the points r on the line
        r0 = cross(F, tangential) / ff
        q = points[i] - com
        r = r0 + (float((q - r0) @ F) / ff) * F
        if float(np.linalg.norm(r - q)) <= MAX_POINT_SHIFT:
            out[i] = com + r
    return out


def soft_wrench_matrix(contacts: FingerContacts, reference: FloatArray) -> FloatArray:
    """W of soft-finger contacts, ``(6, 4k)``: per finger ``[n, t1, t2]`` force columns
    ``[u; p x u]`` (eq. 16) and the torsion column ``[0; n]``, moments about ``reference``
    [m]; zero columns for a finger not touching."""
    w = wrench_matrix(
        contacts.points, contacts.frames, ContactModel.SOFT_FINGER, reference=reference
    )
    if not contacts.active.all():
        w[:, np.repeat(~contacts.active, SOFT_COLUMNS)] = 0.0
    return w


def soft_contact_intensities(contacts: FingerContacts) -> FloatArray:
    """c of soft-finger contacts, ``(4k,)``: per finger [normal, t1, t2] [N], torsion [N m]."""
    k = len(contacts.active)
    c = np.empty((k, SOFT_COLUMNS))
    c[:, :3] = np.einsum("kij,kj->ki", contacts.frames, contacts.force)
    c[:, 3] = contacts.torsion
    return c.reshape(-1)


def soft_finger_cone_margin(c: FloatArray, friction: FloatArray) -> FloatArray:
    """How far inside its friction cone each soft finger's intensities lie, ``(k,)`` [N].

    MuJoCo's elliptic cone of a condim-4 contact (the scene's ``cone="elliptic"``):
    ``c_n >= sqrt((c_t1 / mu)^2 + (c_t2 / mu)^2 + (c_tau / mu_tau)^2)``; the margin is
    the left side minus the right side (>= 0 inside the cone, up to the solver's
    softness).

    Args:
        c: ``(4k,)`` soft-finger intensities (:func:`soft_contact_intensities`).
        friction: ``(k, 2)`` sliding mu [-] and torsional mu_tau [m] per finger
            (:attr:`FingerContacts.friction`).

    Raises:
        ValueError: the shapes do not match.
    """
    cc = np.asarray(c, dtype=float).reshape(-1, SOFT_COLUMNS)
    mu = np.asarray(friction, dtype=float)
    if mu.shape != (len(cc), 2):
        raise ValueError(f"friction must have shape ({len(cc)}, 2), got {mu.shape}")
    tangential = np.hypot(cc[:, 1], cc[:, 2]) / mu[:, 0]
    margin: FloatArray = cc[:, 0] - np.hypot(tangential, cc[:, 3] / mu[:, 1])
    return margin


def pinch_null_basis(W: FloatArray, contacts: FingerContacts) -> FloatArray | None:
    """Orthonormal basis ``(8, 2)`` of null(W) of a soft-finger pinch: squeeze, torsion.

    Two soft fingers (eq. 16 with the torsion column ``[0; n]``) make W ``6 x 8`` of rank 6
    (the torsions produce the moment about the line through the points that two point
    contacts with friction cannot), so G of eq. (8) exists and has two internal forces
    (eq. 6). The basis is named, not an SVD's arbitrary one: column 1 is the squeeze (finger
    1 pushing towards finger 2 and finger 2 back, ``f_int[0] = sqrt(2) s`` for a squeeze of
    s [N] each, positive when squeezing; it lies in null(W) exactly), column 2 the opposed
    torsions (both fingers twisting the pen about their own normals in opposite senses of
    the world, each +1/sqrt(2); projected onto null(W) and made orthogonal to column 1,
    signed so that its torsion of finger 1 is positive). For antipodal normals that is the
    pure torsion pair; where the normals are not opposite (the glove's pen pinch: about 110
    degrees apart) the torsions alone are not internal, and column 2 is mostly opposed
    forces along the pen's axis (t1) whose moment about the chord the torsions balance
    (measured: t1 entries 0.70, torsion entries 0.01, in mixed units N and N m). Being a
    function of W and the contacts, N(t) is as continuous as W(t).

    Args:
        W: ``(6, 8)`` soft-finger wrench matrix
            (:meth:`~ias_gym.sim.glove_contacts.GlovePenPhysics.wrench_matrix`).
        contacts: the contacts W was built from.

    Returns:
        ``(8, 2)`` N with ``W N = 0`` and ``N^T N = I``, or ``None`` unless both fingers
        touch and rank W = 6 (judged as in :mod:`ias_gym.grasp.grip_transform`).
    """
    if W.shape != (6, 2 * SOFT_COLUMNS) or not contacts.active.all():
        return None
    _, s, Vt = np.linalg.svd(W)
    rank = int(np.sum(s > RANK_RTOL * s[0])) if s[0] > 0 else 0
    if rank != 6:
        return None
    null = Vt[6:].T  # (8, 2) some orthonormal basis of null(W)
    towards = contacts.points[1] - contacts.points[0]
    towards = towards / np.linalg.norm(towards)
    squeeze = np.zeros(2 * SOFT_COLUMNS)
    squeeze[0:3] = contacts.frames[0] @ towards
    squeeze[4:7] = -(contacts.frames[1] @ towards)
    normals = contacts.frames[:, 0]
    twist = np.zeros(2 * SOFT_COLUMNS)
    twist[3] = 1.0
    twist[7] = -1.0 if float(normals[0] @ normals[1]) > 0 else 1.0
    n1 = null @ (null.T @ squeeze)
    n1 /= np.linalg.norm(n1)
    n2 = null @ (null.T @ twist)
    n2 -= (n1 @ n2) * n1
    n2 /= np.linalg.norm(n2)
    if n2[3] < 0:
        n2 = -n2
    return np.column_stack([n1, n2])


def squeeze_null_vector(W: FloatArray, contacts: FingerContacts) -> FloatArray | None:
    """The unit null vector N of a two-finger pinch's W, signed so that squeezing is positive.

    With two point contacts with friction, W (6 x 6, eq. 3) has rank 5: no contact force
    makes a moment about the line through the two points. So the grip transform G of
    eq. (8), which needs rank W = 6, does not exist, but null(W) (eq. 6) is one-dimensional:
    the two fingers pushing towards each other along that line, ``c_h = N f_int`` (eq. 7).
    N is signed so that in ``N`` finger 1's force points towards finger 2: then
    ``f_int = N^T c`` (eq. 10) is positive when the fingers squeeze. With the unit N,
    ``f_int = sqrt(2) s`` for a squeeze of s [N] by each finger.

    Args:
        W: ``(6, 6)`` wrench matrix of two fingers
            (:meth:`~ias_gym.sim.glove_contacts.GlovePenPhysics.wrench_matrix`).
        contacts: the contacts W was built from (their points fix the sign).

    Returns:
        ``(6,)`` unit vector with ``W N = 0``, or ``None`` unless both fingers touch and
        rank W = 5 (rank is judged as in :mod:`ias_gym.grasp.grip_transform`).
    """
    if W.shape != (6, 6) or not contacts.active.all():
        return None
    _, s, Vt = np.linalg.svd(W)
    rank = int(np.sum(s > RANK_RTOL * s[0])) if s[0] > 0 else 0
    if rank != PINCH_RANK:
        return None
    N = Vt[-1]
    toward_2 = contacts.points[1] - contacts.points[0]
    force_1 = contacts.frames[0].T @ N[:3]  # finger 1's force in N, paper frame
    return N if force_1 @ toward_2 >= 0 else -N

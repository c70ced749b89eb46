"""The grasp margin: how much stronger a grip is than the least grip that holds (docs/transfer.md).

With the grip transform (eqs. 4-7) the intensities split into ``c = c_p + c_h``: the
particular part ``c_p = W+ f_ext`` carries the object's wrench and the homogeneous part
``c_h = N f_int`` squeezes it. Scaling the squeeze by ``s >= 0`` leaves the wrench on the
object unchanged (``W c_h = 0``); the least scale that keeps every contact inside its
friction cone,

    s* = min { s >= 0 : c_p + s c_h in every cone },

is the least squeeze of the demonstrated kind that still holds the object, and the grasp
margin is ``m = 1 / s*``: ``m = 2`` means the grip squeezes twice as hard as it must,
``m = 1`` that a contact sits on its cone's boundary, ``m < 1`` that it slips. ``m`` is
homogeneous of degree one in ``c_h`` (``c_h -> k c_h`` gives ``m -> k m``), which is what
lets another hand reproduce a demonstrated margin by scaling its own internal forces.

The cones are the true Coulomb cones (not the LP's box or polygon), per contact
``c_n >= 0`` and ``|(c_t1, c_t2)| <= mu c_n``, and for a soft finger (4 intensities per
contact, eq. 3's torsion column) also ``|c_tors| <= mu_t c_n`` with ``mu_t`` a length [m]
(MuJoCo's torsional friction coefficient). Every constraint is convex in the one variable
``s``, so each contact's admissible ``s`` form an interval found in closed form (a quadratic
for the circular cone, two half-lines for torsion) and ``s*`` is the left end of their
intersection; no solver is needed (an LP in one variable has no use for HiGHS).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

#: Relative tolerance of the cone tests [-] (rounding of a product of intensities).
_EPS = 1e-12


def _linear_interval(a: float, b: float) -> tuple[float, float]:
    """The ``s`` with ``a + s b >= 0``: an interval, possibly empty or unbounded."""
    if b > 0:
        return -a / b, math.inf
    if b < 0:
        return -math.inf, -a / b
    return (-math.inf, math.inf) if a >= 0 else (math.inf, -math.inf)


def _cone_interval(
    an: float, at: FloatArray, bn: float, bt: FloatArray, mu: float
) -> tuple[float, float]:
    """The ``s`` with ``|at + s bt| <= mu (an + s bn)``: an interval (the cone is convex).

    The boundary solves ``q(s) = A s^2 + 2 B s + C = 0`` with ``A = |bt|^2 - mu^2 bn^2``,
    ``B = at.bt - mu^2 an bn``, ``C = |at|^2 - mu^2 an^2``; of the region ``q <= 0`` only the
    part with ``an + s bn >= 0`` is the cone (the rest is its mirror image).
    """
    lo_n, hi_n = _linear_interval(an, bn)
    A = float(bt @ bt) - mu * mu * bn * bn
    B = float(at @ bt) - mu * mu * an * bn
    C = float(at @ at) - mu * mu * an * an
    scale = max(float(at @ at) + mu * mu * an * an, float(bt @ bt) + mu * mu * bn * bn, 1e-300)
    if abs(A) <= _EPS * scale:  # q is linear: 2 B s + C <= 0
        if abs(B) <= _EPS * scale:
            return (lo_n, hi_n) if C <= _EPS * scale else (math.inf, -math.inf)
        root = -C / (2.0 * B)
        lo, hi = (root, math.inf) if B < 0 else (-math.inf, root)
        return max(lo, lo_n), min(hi, hi_n)
    disc = B * B - A * C
    if disc < 0:
        # q keeps the sign of A: everywhere inside (A < 0) or nowhere (A > 0)
        return (lo_n, hi_n) if A < 0 else (math.inf, -math.inf)
    root = math.sqrt(disc)
    # the two roots without cancellation
    q = -(B + math.copysign(root, B))
    r1, r2 = sorted((q / A, C / q) if q != 0 else (0.0, 0.0))
    if A > 0:  # inside between the roots; the mirror cone's piece has n < 0
        return max(r1, lo_n), min(r2, hi_n)
    # A < 0: the direction bt, bn points into the cone (bn > 0) or into its mirror (bn < 0)
    if bn > 0:
        return max(r2, lo_n), hi_n
    return lo_n, min(r1, hi_n)


def _contacts(
    c_p: ArrayLike, c_h: ArrayLike, mu: float, mu_torsion: float, intensities: int | None
) -> tuple[FloatArray, FloatArray, int]:
    """``(c_p, c_h, intensities per contact)``, checked (:func:`least_squeeze`'s rules)."""
    a = np.asarray(c_p, dtype=float)
    b = np.asarray(c_h, dtype=float)
    if a.shape != b.shape or a.ndim != 1:
        raise ValueError(f"c_p and c_h must be equal 1-D shapes, got {a.shape} and {b.shape}")
    if mu < 0 or mu_torsion < 0:
        raise ValueError(f"friction coefficients must be >= 0, got mu={mu}, mu_t={mu_torsion}")
    per = intensities or (4 if a.size % 4 == 0 and a.size % 3 else 3)
    if per not in (3, 4) or a.size % per:
        raise ValueError(f"{a.size} intensities are not contacts of {per} (3 or 4) each")
    return a, b, per


def least_squeeze(
    c_p: ArrayLike,
    c_h: ArrayLike,
    mu: float,
    mu_torsion: float = 0.0,
    intensities: int | None = None,
    active: ArrayLike | None = None,
) -> float:
    """The least ``s >= 0`` with ``c_p + s c_h`` inside every contact's friction cone.

    Args:
        c_p: ``(n,)`` particular intensities ``W+ f_ext`` [N] (eq. 5).
        c_h: ``(n,)`` homogeneous (internal) intensities [N] (eq. 7).
        mu: Coulomb friction coefficient [-].
        mu_torsion: torsional friction [m] of soft fingers (4 intensities per contact).
        intensities: intensities per contact, 3 (point with friction) or 4 (soft finger:
            normal, t1, t2, torsion); default 4 if ``n`` is a multiple of 4 but not of 3,
            else 3.
        active: ``(k,)`` bool, contacts that touch (default all); the others are skipped.

    Returns:
        ``s*`` [-]: 0 when ``c_p`` alone is inside the cones, ``inf`` when no squeeze of
        this kind holds the object (or the intensities are not finite).

    Raises:
        ValueError: shapes that do not fit, or a negative friction coefficient.
    """
    a, b, per = _contacts(c_p, c_h, mu, mu_torsion, intensities)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return math.inf
    k = a.size // per
    use = np.ones(k, dtype=bool) if active is None else np.asarray(active, dtype=bool)
    if use.shape != (k,):
        raise ValueError(f"active must have shape ({k},), got {use.shape}")
    lo, hi = 0.0, math.inf
    for i in np.flatnonzero(use):
        li, hi_i = _contact_interval(a, b, int(i), per, mu, mu_torsion)
        lo, hi = max(lo, li), min(hi, hi_i)
    return _left_end(lo, hi)


def _contact_interval(
    a: FloatArray, b: FloatArray, i: int, per: int, mu: float, mu_torsion: float
) -> tuple[float, float]:
    """The squeezes ``s`` that keep contact ``i`` alone inside its cone(s): an interval."""
    ai, bi = a[per * i : per * (i + 1)], b[per * i : per * (i + 1)]
    lo, hi = _cone_interval(ai[0], ai[1:3], bi[0], bi[1:3], mu)
    if per == 4:  # |tors| <= mu_t n: two half-lines
        for sign in (1.0, -1.0):
            l2, h2 = _linear_interval(
                mu_torsion * ai[0] - sign * ai[3], mu_torsion * bi[0] - sign * bi[3]
            )
            lo, hi = max(lo, l2), min(hi, h2)
    return lo, hi


def _left_end(lo: float, hi: float) -> float:
    """``max(lo, 0)`` of a squeeze interval, ``inf`` when it is empty."""
    lo = max(lo, 0.0)
    # an empty intersection up to rounding (a contact exactly on its boundary) still counts
    tol = 1e-9 * max(1.0, abs(lo))
    return lo if lo <= hi + tol else math.inf


def contact_margins(
    c_p: ArrayLike,
    c_h: ArrayLike,
    mu: float,
    mu_torsion: float = 0.0,
    intensities: int | None = None,
) -> FloatArray:
    """Each contact's own margin: ``1 / s_i*``, with ``s_i*`` the least squeeze of the
    demonstrated kind that keeps contact ``i`` alone inside its cone.

    The grasp margin is their minimum (:func:`grasp_margin`: ``s* = max_i s_i*`` when the
    contacts' intervals overlap); a contact with a larger margin squeezes more than it
    needs, relative to the others.

    Args:
        c_p, c_h, mu, mu_torsion, intensities: as :func:`least_squeeze`.

    Returns:
        ``(k,)`` margins [-]: ``inf`` for a contact that needs no squeeze, 0 for one that no
        squeeze of this kind holds, NaN for non-finite input.

    Raises:
        ValueError: as :func:`least_squeeze`.
    """
    a, b, per = _contacts(c_p, c_h, mu, mu_torsion, intensities)
    k = a.size // per
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return np.full(k, np.nan)
    out = np.empty(k)
    for i in range(k):
        s = _left_end(*_contact_interval(a, b, i, per, mu, mu_torsion))
        out[i] = math.inf if s == 0.0 else (0.0 if math.isinf(s) else 1.0 / s)
    return out


def grasp_margin(
    c_p: ArrayLike,
    c_h: ArrayLike,
    mu: float,
    mu_torsion: float = 0.0,
    intensities: int | None = None,
    active: ArrayLike | None = None,
) -> float:
    """The grasp margin ``m = 1 / s*`` of intensities ``c = c_p + c_h`` (module docstring).

    Args:
        c_p, c_h, mu, mu_torsion, intensities, active: as :func:`least_squeeze`.

    Returns:
        ``m`` [-]: > 1 a grip stronger than needed, 1 on a cone's boundary, < 1 slipping;
        ``inf`` when no squeeze is needed, 0 when none holds, NaN for non-finite input.
    """
    if not (np.all(np.isfinite(c_p)) and np.all(np.isfinite(c_h))):
        return math.nan
    s = least_squeeze(c_p, c_h, mu, mu_torsion, intensities, active)
    if s == 0.0:
        return math.inf
    return 0.0 if math.isinf(s) else 1.0 / s


def margin_series(
    c_p: ArrayLike,
    c_h: ArrayLike,
    touching: ArrayLike,
    mu: float,
    mu_torsion: float = 0.0,
) -> FloatArray:
    """``m(t)`` along a skill: the margin of every sample, NaN where a contact is missing.

    Args:
        c_p: ``(T, n)`` particular intensities [N].
        c_h: ``(T, n)`` homogeneous intensities [N] (NaN where they are not defined).
        touching: ``(T, k)`` bool; a sample with a contact off has no margin (NaN).
        mu, mu_torsion: as :func:`least_squeeze`.

    Returns:
        ``(T,)`` margins [-].
    """
    a = np.asarray(c_p, dtype=float)
    b = np.asarray(c_h, dtype=float)
    on = np.asarray(touching, dtype=bool)
    if a.ndim != 2 or a.shape != b.shape or on.ndim != 2 or len(on) != len(a):
        raise ValueError(
            f"c_p, c_h must be (T, n) and touching (T, k), got {a.shape}, {b.shape}, {on.shape}"
        )
    per = a.shape[1] // on.shape[1]
    out = np.full(len(a), np.nan)
    for t in range(len(a)):
        if on[t].all():
            out[t] = grasp_margin(a[t], b[t], mu, mu_torsion, per)
    return out


def scale_to_margin(
    c_p: ArrayLike,
    c_h: ArrayLike,
    margin: float,
    mu: float,
    mu_torsion: float = 0.0,
    intensities: int | None = None,
) -> FloatArray:
    """``k c_h`` with ``k`` such that ``c_p + k c_h`` has the grasp margin ``margin``.

    The margin is homogeneous of degree one in ``c_h``, so ``k = margin s*`` with ``s*``
    the least squeeze of ``c_h`` (:func:`least_squeeze`). A hand executing another hand's
    skill solves its own internal forces (eqs. 19-24) for its own contacts and scales them
    with this to the demonstrated margin.

    Args:
        c_p: ``(n,)`` particular intensities [N].
        c_h: ``(n,)`` the hand's own internal intensities [N].
        margin: the margin to reach [-], > 0.
        mu, mu_torsion, intensities: as :func:`least_squeeze`.

    Returns:
        ``(n,)`` scaled internal intensities [N]; ``c_h`` unchanged when no scale reaches
        the margin (``c_p`` holds alone, ``s* = 0``, or ``c_h`` holds at no scale).

    Raises:
        ValueError: ``margin`` is not a finite positive number.
    """
    if not (math.isfinite(margin) and margin > 0):
        raise ValueError(f"margin must be finite and > 0, got {margin}")
    b = np.asarray(c_h, dtype=float)
    s = least_squeeze(c_p, b, mu, mu_torsion, intensities)
    if s == 0.0 or math.isinf(s):
        return b.copy()
    result: FloatArray = (margin * s) * b
    return result


def tangential_ratios(c: ArrayLike, intensities: int = 3) -> FloatArray:
    """Each contact's ratio of tangential to normal force ``|c_t| / c_n`` [-], NaN where it
    does not press (``c_n <= 0``).

    Every contact force lies in its friction cone, ``|c_t| <= mu c_n``, so no ratio exceeds
    ``mu``, and a contact that slides sits on its cone: its ratio is ``mu`` itself (a
    contact that sticks shows only a lower bound).

    Args:
        c: ``(k * intensities,)`` intensities [N]: normal, t1, t2 (and a torsion moment,
            left out) per contact.
        intensities: 3 or 4 per contact.

    Raises:
        ValueError: ``intensities`` not 3 or 4, or a length that does not fit.
    """
    a = np.asarray(c, dtype=float)
    if intensities not in (3, 4) or a.ndim != 1 or a.size % intensities:
        raise ValueError(f"{a.shape} intensities are not contacts of {intensities} (3 or 4)")
    rows = a.reshape(-1, intensities)
    normal = rows[:, 0]
    tangential = np.hypot(rows[:, 1], rows[:, 2])
    safe = np.where(normal > 0, normal, 1.0)
    out: FloatArray = np.where(normal > 0, tangential / safe, np.nan)
    return out

"""The internal-force problem of eqs. (19)-(24): settings, result, constraint rows, checks.

What :mod:`ias_gym.grasp.internal_forces` describes, without a solver: the settings and the
result types, the friction-cone residual, the sliding direction, the validation of ``W``,
``w_ext`` and the sliding contacts, and the rows of the friction constraints the solvers
share (:mod:`ias_gym.grasp.internal_forces_reference`, the LP and SOCP;
:mod:`ias_gym.grasp.internal_forces_daqp`, the control-loop QP). Units: forces [N].
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ias_gym.errors import (
    InfeasibleGraspError,
)

FloatArray = NDArray[np.float64]
Cone = Literal["box", "exact", "polygon"]
#: The polygon cone's faces: unit directions d in (t1, t2); each face is ``|d . c_t| <= k mu c_n``
#: with ``k = cos(pi / 8)``, the regular octagon inscribed in the circle of radius ``mu c_n``.
POLYGON_DIRECTIONS = np.array(
    [[1.0, 0.0], [0.0, 1.0], [0.5**0.5, 0.5**0.5], [0.5**0.5, -(0.5**0.5)]]
)
POLYGON_SCALE = float(np.cos(np.pi / 8))
SlidingModel = Literal["equality", "paper"]
#: Sliding contacts as {contact index (0-based): unit direction s in (t1, t2) coordinates}.
Sliding = Mapping[int, ArrayLike]

_UNIT_TOL = 1e-6  # allowed | ||s|| - 1 | of a sliding direction [-]
_RANK_TOL = 1e-9  # relative singular value below which equalities are dependent [-]


@dataclass(frozen=True)
class InternalForceSettings:
    """Settings of the internal-force problem (defaults: the docs/NOTES.md pen reference).

    Attributes:
        mu: Coulomb friction coefficient [-].
        f0: minimal normal force of eq. (19) [N].
        cone: ``"box"`` (eqs. 21-24, an LP), ``"exact"`` (Coulomb cone, an SOCP) or
            ``"polygon"`` (the inscribed octagonal pyramid, an LP).
        margin: friction safety margin [-], in [0, 1): sticking contacts use
            ``mu (1 - margin)``.
        sliding: ``"equality"`` (``c_t = mu c_n s``, kinetic friction) or ``"paper"``
            (eq. 20 read literally: ``s . c_t >= mu c_n``, the other component free).
        weights: per-contact weights of the normal forces in the objective [-]
            (``None``: all 1, the plain sum).
    """

    mu: float = 0.25
    f0: float = 0.1
    cone: Cone = "box"
    margin: float = 0.0
    sliding: SlidingModel = "equality"
    weights: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.mu) and self.mu >= 0):
            raise ValueError(f"mu must be finite and >= 0, got {self.mu}")
        if not (np.isfinite(self.f0) and self.f0 >= 0):
            raise ValueError(f"f0 must be finite and >= 0 [N], got {self.f0}")
        if self.cone not in ("box", "exact", "polygon"):
            raise ValueError(f"cone must be 'box', 'exact' or 'polygon', got {self.cone!r}")
        if not 0 <= self.margin < 1:
            raise ValueError(f"margin must be in [0, 1), got {self.margin}")
        if self.sliding not in ("equality", "paper"):
            raise ValueError(f"sliding must be 'equality' or 'paper', got {self.sliding!r}")
        if self.weights is not None and not all(np.isfinite(w) and w > 0 for w in self.weights):
            raise ValueError(f"weights must be finite and > 0, got {self.weights}")

    @property
    def mu_sticking(self) -> float:
        """Friction coefficient of the sticking-cone constraints, ``mu (1 - margin)`` [-]."""
        return self.mu * (1.0 - self.margin)


@dataclass(frozen=True)
class InternalForceResult:
    """An optimal solution of the internal-force problem.

    Attributes:
        c: ``(3 m,)`` wrench intensities [N], per contact ``[normal, t1, t2]`` (read-only).
        objective: weighted sum of the normal forces [N].
        solver: ``"highs"``, ``"clarabel"`` or ``"daqp"``.
        status: the solver's own status text.
    """

    c: FloatArray
    objective: float
    solver: str
    status: str

    @property
    def normal(self) -> FloatArray:
        """``(m,)`` normal forces [N]."""
        return self.c[0::3]

    @property
    def tangential(self) -> FloatArray:
        """``(m, 2)`` tangential forces ``(c_t1, c_t2)`` [N]."""
        return self.c.reshape(-1, 3)[:, 1:]


def friction_cone_residual(c: ArrayLike, mu: float, cone: Cone = "box") -> FloatArray:
    """How far each contact's tangential force exceeds its friction cone [N].

    Args:
        c: ``(3 m,)`` wrench intensities [N], per contact ``[normal, t1, t2]``.
        mu: friction coefficient [-].
        cone: ``"box"`` measures ``max(|c_t1|, |c_t2|)`` (eqs. 21-24), ``"exact"``
            measures ``||(c_t1, c_t2)||``, ``"polygon"`` ``max_d |d . c_t| / cos(pi / 8)``.

    Returns:
        ``(m,)``: tangential measure minus ``mu c_n``; ``<= 0`` inside the cone, ``0`` on it.
    """
    if cone not in ("box", "exact", "polygon"):
        raise ValueError(f"cone must be 'box', 'exact' or 'polygon', got {cone!r}")
    per_contact = np.asarray(c, dtype=float).reshape(-1, 3)
    t = per_contact[:, 1:]
    if cone == "box":
        size = np.abs(t).max(axis=1)
    elif cone == "exact":
        size = np.hypot(t[:, 0], t[:, 1])
    else:
        size = np.abs(t @ POLYGON_DIRECTIONS.T).max(axis=1) / POLYGON_SCALE
    return size - mu * per_contact[:, 0]


def sliding_direction(velocity: ArrayLike, tol: float = 1e-9) -> FloatArray:
    """Unit sliding direction ``s`` of a contact from its tangential velocity.

    Args:
        velocity: ``(2,)`` velocity of the finger relative to the object in (t1, t2)
            coordinates [m/s].
        tol: speed [m/s] at or below which the contact is not sliding.

    Returns:
        ``(2,)`` unit vector along ``velocity`` (the direction of the finger's friction force
        on the object, docs/NOTES.md "Sliding contact").
    """
    v = np.asarray(velocity, dtype=float).reshape(2)
    speed = float(np.hypot(v[0], v[1]))
    if not speed > tol:
        raise ValueError(f"a contact moving at {speed:g} m/s (<= {tol:g}) is not sliding")
    return v / speed


def _check_problem(
    W: ArrayLike, w_ext: ArrayLike, sliding: Sliding | None
) -> tuple[FloatArray, FloatArray, dict[int, FloatArray]]:
    """Validate the inputs shared by all solvers; return them as arrays."""
    W = np.asarray(W, dtype=float)
    w = np.asarray(w_ext, dtype=float)
    if W.ndim != 2 or W.shape[0] != 6 or W.shape[1] == 0 or W.shape[1] % 3:
        raise ValueError(f"W must be 6 x 3m (three columns per contact), got shape {W.shape}")
    if w.shape != (6,):
        raise ValueError(f"w_ext must be a 6-vector [fx fy fz mx my mz], got shape {w.shape}")
    # One sum first (NaN and inf propagate into it; a control loop calls this every step),
    # the exact test only if the sum is not finite (it may overflow).
    if not math.isfinite(float(W.sum()) + float(w.sum())) and not (
        np.isfinite(W).all() and np.isfinite(w).all()
    ):
        raise ValueError("W and w_ext must be finite (found NaN or inf)")
    m = W.shape[1] // 3
    slides: dict[int, FloatArray] = {}
    for k, s in (sliding or {}).items():
        s_arr = np.asarray(s, dtype=float)
        if not isinstance(k, (int, np.integer)) or not 0 <= k < m:
            raise ValueError(f"sliding contact index {k!r} is not one of 0..{m - 1}")
        if s_arr.shape != (2,) or not np.isfinite(s_arr).all():
            raise ValueError(f"sliding direction of contact {k} must be a finite 2-vector")
        if abs(np.hypot(s_arr[0], s_arr[1]) - 1.0) > _UNIT_TOL:
            raise ValueError(f"sliding direction of contact {k} must be a unit vector: {s_arr}")
        slides[int(k)] = s_arr
    return W, w, slides


def _check_weights(settings: InternalForceSettings, m: int) -> FloatArray:
    """Objective vector: the contact weights on the normal intensities, 0 on the tangents."""
    weights = np.ones(m) if settings.weights is None else np.asarray(settings.weights)
    if weights.shape != (m,):
        raise ValueError(f"settings.weights has {weights.size} entries for {m} contacts")
    cost = np.zeros(3 * m)
    cost[0::3] = weights
    return cost


def _friction_rows(
    m: int, sliding: dict[int, FloatArray], settings: InternalForceSettings, sticking: bool
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Linear friction constraints ``lower <= F c <= upper`` (eqs. 20-24).

    Args:
        m: number of contacts.
        sliding: validated sliding directions.
        settings: problem settings.
        sticking: include the box cones of the sticking contacts (eqs. 21-24).

    Returns:
        ``(F, lower, upper)``; equal bounds mark equalities.
    """
    rows: list[FloatArray] = []
    bounds: list[tuple[float, float]] = []

    def row(j: int, normal: float, t1: float, t2: float, lo: float, up: float) -> None:
        r = np.zeros(3 * m)
        r[3 * j : 3 * j + 3] = normal, t1, t2
        rows.append(r)
        bounds.append((lo, up))

    mu, mu_s = settings.mu, settings.mu_sticking
    for j in range(m):
        if j in sliding:
            s1, s2 = sliding[j]
            if settings.sliding == "equality":  # c_t - mu c_n s = 0
                row(j, -mu * s1, 1.0, 0.0, 0.0, 0.0)
                row(j, -mu * s2, 0.0, 1.0, 0.0, 0.0)
            else:  # eq. (20) along s: s . c_t - mu c_n >= 0
                row(j, -mu, s1, s2, 0.0, np.inf)
        elif sticking and settings.cone == "polygon":  # -k mu c_n <= d . c_t <= k mu c_n
            for d1, d2 in POLYGON_DIRECTIONS:
                row(j, -POLYGON_SCALE * mu_s, d1, d2, -np.inf, 0.0)
                row(j, POLYGON_SCALE * mu_s, d1, d2, 0.0, np.inf)
        elif sticking:  # eqs. (21)-(24): -mu c_n <= c_ti <= mu c_n
            row(j, -mu_s, 1.0, 0.0, -np.inf, 0.0)
            row(j, mu_s, 1.0, 0.0, 0.0, np.inf)
            row(j, -mu_s, 0.0, 1.0, -np.inf, 0.0)
            row(j, mu_s, 0.0, 1.0, 0.0, np.inf)
    F = np.array(rows).reshape(-1, 3 * m)
    lower, upper = np.array(bounds).reshape(-1, 2).T
    return F, lower, upper


def _infeasible(
    m: int,
    w_ext: FloatArray,
    sliding: dict[int, FloatArray],
    settings: InternalForceSettings,
    detail: str,
) -> InfeasibleGraspError:
    """The error for an infeasible problem, naming every contact and constraint."""
    contacts = ", ".join(
        f"{j} sliding s=({sliding[j][0]:g},{sliding[j][1]:g})" if j in sliding else f"{j} sticking"
        for j in range(m)
    )
    wrench = ", ".join(f"{x:g}" for x in w_ext)
    return InfeasibleGraspError(
        f"no wrench intensities satisfy equilibrium W c = -w_ext (w_ext=[{wrench}]) with "
        f"normals >= f0={settings.f0:g} N and friction cones (mu={settings.mu:g}, {settings.cone}, "
        f"margin={settings.margin:g}, sliding {settings.sliding}) for contacts "
        f"[{contacts}] ({detail})"
    )


def _unit_rows(A: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``A x = b`` with unit-norm rows (zero rows kept).

    W's moment rows are ~r times its force rows; solvers hold every row to one absolute
    tolerance (HiGHS: 1e-7), which on a raw moment row would leave 1e-7 / r N of slack.
    """
    norms = np.sqrt(np.einsum("ij,ij->i", A, A))
    scale = 1.0 / np.where(norms > 0, norms, 1.0)
    return A * scale[:, None], b * scale


def _independent_equalities(A: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray] | None:
    """Independent rows equivalent to ``A x = b``, or ``None`` if ``A x = b`` has no solution.

    An interior-point method needs independent equalities, and two contacts already give a
    rank-deficient ``W`` (no moment about the line through them).
    """
    A, b = _unit_rows(A, b)
    U, sv, Vt = np.linalg.svd(A, full_matrices=False)
    rank = int((sv > _RANK_TOL * sv[0]).sum()) if sv.size and sv[0] > 0 else 0
    U = U[:, :rank]
    if np.linalg.norm(b - U @ (U.T @ b)) > _RANK_TOL * max(1.0, float(np.linalg.norm(b))):
        return None
    return sv[:rank, None] * Vt[:rank], U.T @ b


def _result(c: FloatArray, cost: FloatArray, solver: str, status: str) -> InternalForceResult:
    c = np.array(c, dtype=float)
    c.setflags(write=False)
    return InternalForceResult(c=c, objective=float(cost @ c), solver=solver, status=status)


def _require_cone(settings: InternalForceSettings, cones: tuple[Cone, ...], name: str) -> None:
    if settings.cone not in cones:
        raise ValueError(
            f"{name} solves cone={' or '.join(map(repr, cones))} problems, settings.cone is "
            f"{settings.cone!r} (solve_internal_forces picks the solver from settings.cone)"
        )

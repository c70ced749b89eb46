"""Internal grasp forces by optimisation, eqs. (19)-(24).

Given the wrench matrix ``W`` of eq. (3) (the modern *grasp matrix*) of ``m`` hard-finger
contacts and the external wrench ``w_ext`` on the object, find the wrench intensities ``c``
(per contact ``[normal, t1, t2]``, the column order of
:func:`ias_gym.grasp.contacts.wrench_matrix`; a compressive contact has ``c_n > 0``) that

- hold the object: ``W c = -w_ext`` (the fingers cancel the external wrench, e.g. the weight
  ``w_ext = [0, -m g, 0, 0, 0, 0]`` of eq. 18; docs/NOTES.md "Sign of gravity");
- keep every contact closed: ``c_n >= f0`` (eq. 19);
- keep sticking contacts inside their friction cone: the paper's box
  ``|c_t1| <= mu c_n, |c_t2| <= mu c_n`` (eqs. 21-24), the exact Coulomb cone
  ``||(c_t1, c_t2)|| <= mu c_n``, or an eight-sided pyramid inscribed in it (``"polygon"``:
  linear like the box, but never outside the true cone; the box's corners are ``sqrt(2)``
  outside it, docs/controller.md);
- put a sliding contact's tangential force on the cone in its sliding direction,
  ``(c_t1, c_t2) = mu c_n s`` (kinetic Coulomb friction, docs/NOTES.md "Sliding contact"), where
  ``s`` is the unit direction of the finger's velocity relative to the object in (t1, t2)
  coordinates; the paper's eq. (20), ``c_t1 + mu c_n < 0``, is the case ``s = (-1, 0)``;

and minimise the (weighted) sum of the normal forces.

Our choices, beyond the paper: the equality for sliding contacts (the paper-literal
inequality is kept as ``sliding="paper"``, generalised to ``s . c_t >= mu c_n``; it lets the
optimum pick tangential forces a contact cannot deliver); the exact cone; and a friction safety
``margin``: sticking contacts use ``mu (1 - margin)`` because the minimum-force optimum sits
exactly on the cone boundary. Sliding contacts always use the true ``mu``.

Solvers (times per solve of the 4-finger pen, ``bench/bench_internal_forces.py``):

- :func:`solve_lp`: ``scipy.optimize.linprog(method="highs")``, the paper-faithful
  reference (box cones), about 1.6 ms;
- :func:`solve_socp`: Clarabel, exact cones, about 0.4 ms;
- :class:`InternalForceSolver`: the control-loop path, a persistent, warm-started DAQP
  workspace solving the box-cone problem as a slightly regularised QP, about 25 us;
- :func:`solve_internal_forces`: picks :func:`solve_lp` or :func:`solve_socp` from
  ``settings.cone``.

Units are SI: forces [N], moments [N m].
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import clarabel
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import sparse
from scipy.optimize import linprog

from ias_gym.errors import IasGymError

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
_DAQP_PRIMAL_TOL = 1e-9  # DAQP's constraint tolerance [N] (its default 1e-6 is coarse)


class InfeasibleGraspError(IasGymError, ValueError):
    """No wrench intensities satisfy equilibrium, the normal-force bound and the cones."""


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
    if not (np.isfinite(W).all() and np.isfinite(w).all()):
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


def solve_lp(
    W: ArrayLike,
    w_ext: ArrayLike,
    sliding: Sliding | None = None,
    settings: InternalForceSettings | None = None,
) -> InternalForceResult:
    """The paper's internal-force LP, eqs. (19)-(24), with HiGHS (the reference solver).

    Box friction cones; ``scipy.optimize.linprog(method="highs")``, or Clarabel on the same LP
    when HiGHS reports numerical difficulties (``result.solver`` says which). The optimum is
    a vertex and need not be unique (the pen's is not).

    Args:
        W: ``(6, 3 m)`` wrench matrix of eq. (3), columns ``[normal, t1, t2]`` per contact.
        w_ext: ``(6,)`` external wrench on the object [N, N m]; the contacts supply ``-w_ext``.
        sliding: {contact index (0-based): unit direction ``s`` in (t1, t2)}; ``None``: all
            contacts stick.
        settings: problem settings (``None``: the defaults); ``settings.cone`` "box" or "polygon".

    Returns:
        The optimal wrench intensities.

    Raises:
        InfeasibleGraspError: no intensities satisfy the constraints.
        ValueError: bad shapes, non-finite inputs, or ``settings.cone == "exact"``.
        RuntimeError: neither HiGHS nor Clarabel could decide (not seen so far).
    """
    settings = InternalForceSettings() if settings is None else settings
    _require_cone(settings, ("box", "polygon"), "solve_lp")
    W, w, slides = _check_problem(W, w_ext, sliding)
    m = W.shape[1] // 3
    cost = _check_weights(settings, m)
    F, lower, upper = _friction_rows(m, slides, settings, sticking=True)
    W_unit, rhs = _unit_rows(W, -w)
    eq = lower == upper
    has_up, has_lo = ~eq & np.isfinite(upper), ~eq & np.isfinite(lower)
    A_ub = np.vstack([F[has_up], -F[has_lo]])
    b_ub = np.concatenate([upper[has_up], -lower[has_lo]])
    # linprog's default bounds are (0, None): the tangential intensities must be free.
    bounds = [(settings.f0, None), (None, None), (None, None)] * m
    res = linprog(
        cost,
        A_ub=A_ub if len(A_ub) else None,
        b_ub=b_ub if len(b_ub) else None,
        A_eq=np.vstack([W_unit, F[eq]]),
        b_eq=np.concatenate([rhs, lower[eq]]),
        bounds=bounds,
        method="highs",
    )
    if res.status == 4:
        # HiGHS gives up ("numerical difficulties") on a few degenerate problems: three
        # orthogonal contacts at mu = 0.5, where only c = 0 balances the normals; two
        # coincident contacts. Clarabel's interior point decides those.
        return _solve_clarabel(W, w, slides, settings)
    if res.status == 2:
        raise _infeasible(m, w, slides, settings, f"highs: {res.message}")
    if res.status != 0:
        raise RuntimeError(f"linprog(highs) failed on the internal-force LP: {res.message}")
    return _result(res.x, cost, "highs", str(res.message))


def solve_socp(
    W: ArrayLike,
    w_ext: ArrayLike,
    sliding: Sliding | None = None,
    settings: InternalForceSettings | None = None,
) -> InternalForceResult:
    """The internal-force problem with exact Coulomb cones, a second-order cone program.

    Eqs. (19)-(20) as in :func:`solve_lp`; the box of eqs. (21)-(24) becomes
    ``||(c_t1, c_t2)|| <= mu (1 - margin) c_n`` for each sticking contact. Solved by Clarabel
    called directly (not through cvxpy): it is maintained, a pure conic interior-point method
    with exact second-order cones, a small dependency that needs only scipy's sparse
    matrices, and fast (about 0.3 ms in Clarabel per pen solve, 0.4 ms per call).
    Interior-point methods need independent equalities, so they are reduced first (an SVD);
    equalities without any solution are reported as infeasible right there.

    Args:
        W: ``(6, 3 m)`` wrench matrix of eq. (3), columns ``[normal, t1, t2]`` per contact.
        w_ext: ``(6,)`` external wrench on the object [N, N m]; the contacts supply ``-w_ext``.
        sliding: {contact index (0-based): unit direction ``s`` in (t1, t2)}; ``None``: all
            contacts stick.
        settings: problem settings (``None``: the defaults with ``cone="exact"``);
            ``settings.cone`` must be "exact".

    Returns:
        The optimal wrench intensities (to the interior-point tolerance, about 1e-8).

    Raises:
        InfeasibleGraspError: no intensities satisfy the constraints.
        ValueError: bad shapes, non-finite inputs, or ``settings.cone == "box"``.
        RuntimeError: Clarabel could not decide (only seen at the very edge of feasibility).
    """
    settings = InternalForceSettings(cone="exact") if settings is None else settings
    _require_cone(settings, ("exact",), "solve_socp")
    W, w, slides = _check_problem(W, w_ext, sliding)
    return _solve_clarabel(W, w, slides, settings)


def _solve_clarabel(
    W: FloatArray, w: FloatArray, slides: dict[int, FloatArray], settings: InternalForceSettings
) -> InternalForceResult:
    """Solve the checked problem with Clarabel, box or exact cones as ``settings.cone``."""
    m = W.shape[1] // 3
    n = 3 * m
    cost = _check_weights(settings, m)
    exact = settings.cone == "exact"
    F, lower, upper = _friction_rows(m, slides, settings, sticking=not exact)
    eq = lower == upper
    has_up, has_lo = ~eq & np.isfinite(upper), ~eq & np.isfinite(lower)
    equalities = _independent_equalities(np.vstack([W, F[eq]]), np.concatenate([-w, lower[eq]]))
    if equalities is None:
        detail = "equilibrium and the sliding equalities alone have no solution"
        raise _infeasible(m, w, slides, settings, detail)
    sticking = [j for j in range(m) if j not in slides] if exact else []
    # Clarabel: A x + s = b with s in the cones, in this row order.
    soc = np.zeros((3 * len(sticking), n))
    for i, j in enumerate(sticking):  # s = (mu c_n, c_t1, c_t2) in the second-order cone
        soc[3 * i : 3 * i + 3, 3 * j : 3 * j + 3] = -np.diag([settings.mu_sticking, 1.0, 1.0])
    blocks = [
        equalities,  # zero cone
        (-np.eye(n)[0::3], np.full(m, -settings.f0)),  # c_n >= f0
        (F[has_up], upper[has_up]),
        (-F[has_lo], -lower[has_lo]),
        (soc, np.zeros(len(soc))),
    ]
    A = sparse.csc_matrix(np.vstack([rows for rows, _ in blocks]))
    b = np.concatenate([rhs for _, rhs in blocks])
    n_eq = len(blocks[0][1])
    n_ineq = sum(len(rhs) for _, rhs in blocks[1:4])
    cones: list[Any] = [clarabel.ZeroConeT(n_eq), clarabel.NonnegativeConeT(n_ineq)]
    cones += [clarabel.SecondOrderConeT(3) for _ in sticking]
    options = clarabel.DefaultSettings()
    options.verbose = False
    solver = clarabel.DefaultSolver(sparse.csc_matrix((n, n)), cost, A, b, cones, options)
    solution = solver.solve()
    status = str(solution.status)
    if solution.status in (
        clarabel.SolverStatus.PrimalInfeasible,
        clarabel.SolverStatus.AlmostPrimalInfeasible,
    ):
        raise _infeasible(m, w, slides, settings, f"clarabel: {status}")
    if solution.status not in (clarabel.SolverStatus.Solved, clarabel.SolverStatus.AlmostSolved):
        raise RuntimeError(f"clarabel failed on the internal-force problem: {status}")
    return _result(np.asarray(solution.x), cost, "clarabel", status)


def solve_internal_forces(
    W: ArrayLike,
    w_ext: ArrayLike,
    sliding: Sliding | None = None,
    settings: InternalForceSettings | None = None,
) -> InternalForceResult:
    """Solve eqs. (19)-(24) with the solver ``settings.cone`` calls for.

    ``"box"``: :func:`solve_lp`; ``"exact"``: :func:`solve_socp`. Arguments, result and
    errors as theirs (``settings=None``: the defaults, box cones).
    """
    settings = InternalForceSettings() if settings is None else settings
    solve = solve_socp if settings.cone == "exact" else solve_lp
    return solve(W, w_ext, sliding, settings)


class InternalForceSolver:
    """The internal-force problem of eqs. (19)-(24) for a control loop (box cones).

    Built once for a contact count and settings; each :meth:`solve` copies the new ``W`` and
    ``w_ext`` into a persistent DAQP workspace (a dual active-set QP solver) and warm-starts
    from the previous active set: about 5 us in DAQP, 25 us per call with the input checks,
    against about 1.6 ms for :func:`solve_lp`. A change of the sliding contacts rebuilds the
    workspace (a cold start, about 0.1 ms).

    The LP is solved as the QP ``min cost . c + (eps / 2) ||c||^2``, regularising every
    intensity so that the Hessian is positive definite as DAQP needs. For small enough ``eps``
    the QP's optimum is exactly the least-norm point of the LP's optimal face (exact
    regularisation, Mangasarian and Meyer 1979), so the sum of normal forces equals
    :func:`solve_lp`'s (to 1e-12 N on the pen) while the optimum is unique: the forces move
    continuously with ``W`` instead of jumping between the LP's vertices, and a warm start
    cannot change the answer.

    Why DAQP: a persistent HiGHS model whose ``W`` coefficients are changed in place and
    warm-started needs about 90 us per call, most of it in the 72 ``changeCoeff`` calls;
    ``daqp.solve`` without a workspace about 50 us (``bench/bench_internal_forces.py``).
    If DAQP rejects a problem (equalities it cannot tell from inconsistent ones, possible
    when ``W`` is rank-deficient) the call falls back to :func:`solve_lp` (``result.solver``
    then names HiGHS or Clarabel). DAQP is imported when the solver is built, so the rest
    of this module works without it.
    """

    def __init__(
        self,
        n_contacts: int,
        settings: InternalForceSettings | None = None,
        regularisation: float = 1e-6,
    ) -> None:
        """Prepare the solver.

        Args:
            n_contacts: number of contacts m (three wrench intensities each).
            settings: problem settings (``None``: the defaults); cone "box" or "polygon".
            regularisation: ``eps`` of the QP's ``(eps / 2) ||c||^2`` [1/N].
        """
        try:
            import daqp
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise ImportError("InternalForceSolver needs daqp: pip install daqp") from exc
        settings = InternalForceSettings() if settings is None else settings
        _require_cone(settings, ("box", "polygon"), "InternalForceSolver")
        if n_contacts < 1:
            raise ValueError(f"n_contacts must be >= 1, got {n_contacts}")
        if not (np.isfinite(regularisation) and regularisation > 0):
            raise ValueError(f"regularisation must be finite and > 0, got {regularisation}")
        self.n_contacts = n_contacts
        self.settings = settings
        self._daqp = daqp
        n = 3 * n_contacts
        self._cost = _check_weights(settings, n_contacts)
        self._H = regularisation * np.eye(n)
        # DAQP takes the variable bounds as the first n entries of the bound vectors.
        self._var_lower = np.tile([settings.f0, -np.inf, -np.inf], n_contacts)
        self._var_upper = np.full(n, np.inf)
        self._model: Any = None
        self._sliding_key: tuple[tuple[int, float, float], ...] | None = None
        self._A = np.zeros((0, n))
        self._lower = np.zeros(0)
        self._upper = np.zeros(0)

    def solve(
        self, W: ArrayLike, w_ext: ArrayLike, sliding: Sliding | None = None
    ) -> InternalForceResult:
        """Solve for the wrench intensities; arguments and errors as :func:`solve_lp`'s.

        Args:
            W: ``(6, 3 m)`` wrench matrix, ``m = n_contacts``.
            w_ext: ``(6,)`` external wrench on the object [N, N m].
            sliding: {contact index (0-based): unit direction ``s`` in (t1, t2)} or ``None``.

        Returns:
            The optimal wrench intensities (``solver="daqp"``).
        """
        W, w, slides = _check_problem(W, w_ext, sliding)
        m, n = self.n_contacts, 3 * self.n_contacts
        if W.shape[1] != n:
            raise ValueError(f"W has {W.shape[1] // 3} contacts, this solver {m}")
        W_unit, rhs = _unit_rows(W, -w)
        key = tuple((j, float(s[0]), float(s[1])) for j, s in sorted(slides.items()))
        if key == self._sliding_key:
            self._A[:6] = W_unit
            self._lower[n : n + 6] = self._upper[n : n + 6] = rhs
            ready = self._model.update(A=self._A, bupper=self._upper, blower=self._lower) >= 0
        else:
            ready = self._setup(W_unit, rhs, slides)
        if ready:
            x, _, flag, _ = self._model.solve()
            if flag == 1:
                self._sliding_key = key
                return _result(x, self._cost, "daqp", "optimal")
            if flag == -1:
                self._sliding_key = None
                raise _infeasible(m, w, slides, self.settings, "daqp: infeasible")
        # DAQP refuses equalities it cannot tell apart from inconsistent ones (e.g. two
        # contacts: rank W = 5); rare, and the LP decides those.
        self._sliding_key = None
        return solve_lp(W, w, slides, self.settings)

    def _setup(self, W: FloatArray, rhs: FloatArray, slides: dict[int, FloatArray]) -> bool:
        """Build the workspace for a new set of sliding contacts (cold start).

        Returns:
            Whether DAQP accepted the problem.
        """
        F, lower, upper = _friction_rows(self.n_contacts, slides, self.settings, sticking=True)
        self._A = np.vstack([W, F])
        self._lower = np.concatenate([self._var_lower, rhs, lower])
        self._upper = np.concatenate([self._var_upper, rhs, upper])
        n = len(self._var_lower)
        sense = np.zeros(len(self._lower), dtype=np.int32)
        sense[n:][np.concatenate([np.ones(6, dtype=bool), lower == upper])] = 5  # equalities
        self._model = self._daqp.Model()
        self._model.settings = {"primal_tol": _DAQP_PRIMAL_TOL}
        flag, _ = self._model.setup(self._H, self._cost, self._A, self._upper, self._lower, sense)
        return bool(flag >= 0)

"""The reference solvers of the internal-force problem: HiGHS LP (box cones) and Clarabel
SOCP (exact and polygon cones), and :func:`solve_internal_forces` picking one from the
settings (see :mod:`ias_gym.grasp.internal_forces` for the problem). Units: forces [N].
"""

from __future__ import annotations

from typing import Any

import clarabel
import numpy as np
from numpy.typing import ArrayLike
from scipy import sparse
from scipy.optimize import linprog

from ias_gym.grasp.internal_forces_problem import (
    FloatArray,
    InternalForceResult,
    InternalForceSettings,
    Sliding,
    _check_problem,
    _check_weights,
    _friction_rows,
    _independent_equalities,
    _infeasible,
    _require_cone,
    _result,
    _unit_rows,
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

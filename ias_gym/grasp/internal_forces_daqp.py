"""The control-loop solver of the internal-force problem: a persistent, warm-started DAQP
workspace (:class:`InternalForceSolver`, box cones), falling back to the reference solvers
(see :mod:`ias_gym.grasp.internal_forces` for the problem). Units: forces [N].
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ias_gym.grasp.internal_forces_problem import (
    FloatArray,
    InternalForceResult,
    InternalForceSettings,
    Sliding,
    _check_problem,
    _check_weights,
    _friction_rows,
    _infeasible,
    _require_cone,
    _result,
    _unit_rows,
)
from ias_gym.grasp.internal_forces_reference import solve_lp

_DAQP_PRIMAL_TOL = 1e-9  # DAQP's constraint tolerance [N] (its default 1e-6 is coarse)


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

"""Time the internal-force solvers of ``ias_gym.grasp.internal_forces`` side by side.

The problem: the paper's pen (docs/NOTES.md reference: mu = 0.25, r = 1 cm, m g = 1 N, f0 = 0.1 N)
in phase 1 of eq. (17), finger 1 sliding to -x while phi_1 grows from 3 to 4 cm. Each
repetition solves the next W along that slide, as a control loop would, so warm starts are
honest. Also timed, as the alternatives we did not ship (built here from the module's own
friction rows): DAQP called cold each time, and a persistent HiGHS model whose W
coefficients are changed in place and warm-started.

Run: ``python bench/bench_internal_forces.py [--reps N] [--json FILE]``.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import daqp
import highspy
import numpy as np
from report import Report

from ias_gym.grasp.internal_forces import (
    InternalForceSettings,
    InternalForceSolver,
    solve_lp,
    solve_socp,
)
from ias_gym.grasp.internal_forces_problem import _friction_rows
from ias_gym.grasp.wrench_matrix import wrench_matrix

RADIUS = 0.01  # pen radius r [m]
WEIGHT = 1.0  # m g [N]
SETTINGS = InternalForceSettings(mu=0.25, f0=0.1)
SLIDING = {0: np.array([-1.0, 0.0])}  # phase 1: finger 1 slides to -x
W_EXT = np.array([0.0, -WEIGHT, 0.0, 0.0, 0.0, 0.0])


def pen_w(phi: np.ndarray) -> np.ndarray:
    """W of eq. (16) for finger distances phi [m] (docs/NOTES.md geometry)."""
    points = [
        (-phi[0], RADIUS, 0),
        (-phi[1], -RADIUS, 0),
        (phi[2], -RADIUS, 0),
        (phi[3], RADIUS, 0),
    ]
    normals = [(0, -1, 0), (0, 1, 0), (0, 1, 0), (0, -1, 0)]
    return wrench_matrix(points, [[n, (1, 0, 0), (0, 0, 1)] for n in normals])


def daqp_cold(W: np.ndarray) -> float:
    """One-shot ``daqp.solve`` of the same regularised QP, no workspace reuse."""
    F, lower, upper = _friction_rows(4, SLIDING, SETTINGS, sticking=True)
    A = np.vstack([W, F])
    lo = np.concatenate([np.tile([SETTINGS.f0, -np.inf, -np.inf], 4), -W_EXT, lower])
    up = np.concatenate([np.full(12, np.inf), -W_EXT, upper])
    sense = np.zeros(len(lo), dtype=np.int32)
    sense[12:][np.concatenate([np.ones(6, dtype=bool), lower == upper])] = 5
    cost = np.tile([1.0, 0.0, 0.0], 4)
    x, _, flag, _ = daqp.solve(1e-6 * np.eye(12), cost, A, up, lo, sense)
    assert flag == 1
    return float(x[0::3].sum())


class PersistentHighs:
    """The LP in one HiGHS model; each solve changes W's coefficients in place, warm basis."""

    def __init__(self, W: np.ndarray) -> None:
        F, lower, upper = _friction_rows(4, SLIDING, SETTINGS, sticking=True)
        A = np.vstack([W, F])
        rows = len(A)
        inf = highspy.kHighsInf
        self.h = highspy.Highs()
        self.h.setOptionValue("output_flag", False)
        self.h.passModel(
            12,
            rows,
            A.size,
            int(highspy.MatrixFormat.kColwise),
            int(highspy.ObjSense.kMinimize),
            0.0,
            np.tile([1.0, 0.0, 0.0], 4),
            np.tile([SETTINGS.f0, -inf, -inf], 4),
            np.full(12, inf),
            np.concatenate([-W_EXT, np.maximum(lower, -inf)]),
            np.concatenate([-W_EXT, np.minimum(upper, inf)]),
            np.arange(0, A.size, rows, dtype=np.int32),
            np.tile(np.arange(rows, dtype=np.int32), 12),
            A.T.ravel().copy(),
            np.zeros(12, dtype=np.int32),
        )

    def solve(self, W: np.ndarray) -> float:
        for i in range(6):
            for j in range(12):
                self.h.changeCoeff(i, j, W[i, j])
        self.h.run()
        assert self.h.getModelStatus() == highspy.HighsModelStatus.kOptimal
        return float(np.asarray(self.h.getSolution().col_value)[0::3].sum())


def time_solver(solve: Callable[[np.ndarray], float], ws: list[np.ndarray]) -> np.ndarray:
    """Per-call wall times [us], after a warm-up pass; also checks the objective (1.4 N)."""
    for W in ws[:20]:
        objective = solve(W)
        assert abs(objective - 1.4) < 1e-6, objective
    times = np.empty(len(ws))
    for i, W in enumerate(ws):
        start = time.perf_counter()
        solve(W)
        times[i] = time.perf_counter() - start
    return times * 1e6


def main() -> None:
    """The table: solver, median and p90 per solve [us], linprog's median / its median."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=2000, help="solves per solver")
    report, args = Report.start(parser)
    phis = np.linspace(0.03, 0.04, args.reps)
    ws = [pen_w(np.array([p, 0.02, 0.02, 0.03])) for p in phis]
    fast = InternalForceSolver(4, SETTINGS)
    highs = PersistentHighs(ws[0])
    solvers: dict[str, Callable[[np.ndarray], float]] = {
        "`solve_lp`: linprog, HiGHS (paper-faithful, box cones)": lambda W: (
            solve_lp(W, W_EXT, SLIDING, SETTINGS).objective
        ),
        "`solve_socp`: Clarabel (exact cones)": lambda W: solve_socp(W, W_EXT, SLIDING).objective,
        "`InternalForceSolver`: warm DAQP QP (control loops)": lambda W: (
            fast.solve(W, W_EXT, SLIDING).objective
        ),
        "daqp cold, for comparison": daqp_cold,
        "persistent highspy, coefficients updated in place, for comparison": highs.solve,
    }
    stats = {name: time_solver(solve, ws) for name, solve in solvers.items()}
    ref = float(np.median(next(iter(stats.values()))))
    table = report.table(
        f"The pen in phase 1 (finger 1 sliding), {args.reps} solves per solver",
        ["solver", "median [us]", "p90 [us]", "speed-up"],
    )
    for name, t in stats.items():
        median, p90 = float(np.median(t)), float(np.percentile(t, 90))
        table.row(name, f"{median:.1f}", f"{p90:.1f}", f"{ref / median:.1f}")
    report.finish()


if __name__ == "__main__":
    main()

"""The inscribed polygon friction cone (``cone="polygon"``) of the internal-force problem.

The controller plans with it (docs/controller.md): linear like the paper's box, but never
outside the true Coulomb cone, which the box's corners are (sqrt(2) times the radius).
"""

from __future__ import annotations

import numpy as np
import pytest

from ias_gym.grasp.internal_forces import (
    POLYGON_DIRECTIONS,
    POLYGON_SCALE,
    InternalForceSettings,
    InternalForceSolver,
    friction_cone_residual,
    solve_lp,
    solve_socp,
)
from tests.test_internal_forces import GRAVITY, PHI, assert_satisfies_constraints, pen_w, phase

POLYGON = InternalForceSettings(mu=0.25, f0=0.2, cone="polygon", margin=0.4)


def test_polygon_is_inscribed_in_the_circle() -> None:
    """Its vertices lie on the circle of radius mu c_n, its faces at cos(pi/8) of it."""
    angles = np.arange(16) * np.pi / 8
    on_circle = np.column_stack([np.ones(16), 0.25 * np.cos(angles), 0.25 * np.sin(angles)])
    residual = friction_cone_residual(on_circle.ravel(), 0.25, "polygon")
    # Directions between faces' normals (the vertices, odd multiples of pi/8) are exactly on it;
    # every point of the circle is on or outside the polygon.
    assert residual.min() >= -1e-12
    np.testing.assert_allclose(residual[1::2], 0.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(POLYGON_DIRECTIONS, axis=1), 1.0)
    assert POLYGON_SCALE == pytest.approx(np.cos(np.pi / 8))


@pytest.mark.parametrize("k", range(4))
def test_polygon_solutions_stay_inside_the_true_cone(k: int) -> None:
    """Along the sliding skill, LP and fast path with the polygon: every sticking contact is
    inside the exact cone of mu (1 - margin), and both solvers agree on the optimum."""
    W = pen_w(PHI)
    lp = solve_lp(W, GRAVITY, phase(k), POLYGON)
    fast = InternalForceSolver(4, POLYGON).solve(W, GRAVITY, phase(k))
    for result in (lp, fast):
        assert_satisfies_constraints(result, W, GRAVITY, phase(k), POLYGON)
        exact = friction_cone_residual(result.c, POLYGON.mu_sticking, "exact")
        sticking = [j for j in range(4) if j != k]
        assert exact[sticking].max() <= 1e-9
    assert fast.objective == pytest.approx(lp.objective, abs=1e-6)


def test_the_box_can_leave_the_true_cone_where_the_polygon_cannot() -> None:
    """A lateral and an axial load together: the box optimum uses a corner outside the exact
    cone; the polygon's does not (and needs more squeeze for it)."""
    W = pen_w(PHI)
    load = GRAVITY + np.array([0.3, 0.0, 0.3, 0.0, 0.0, 0.0])
    box = InternalForceSettings(mu=0.25, f0=0.2)
    polygon = InternalForceSettings(mu=0.25, f0=0.2, cone="polygon")
    box_result = solve_lp(W, load, None, box)
    polygon_result = solve_lp(W, load, None, polygon)
    assert friction_cone_residual(box_result.c, 0.25, "exact").max() > 1e-3
    assert friction_cone_residual(polygon_result.c, 0.25, "exact").max() <= 1e-9
    exact = solve_socp(W, load, None, InternalForceSettings(mu=0.25, f0=0.2, cone="exact"))
    assert box_result.objective <= exact.objective + 1e-9 <= polygon_result.objective + 2e-9

# Over 450 lines: every test here runs the same problem through all three solvers (LP, SOCP, DAQP).
"""The internal-force optimisation of eqs. (19)-(24): pen reference, constraints, solvers."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import assume, event, given, settings
from hypothesis import strategies as st
from paper_reference import eq16

from ias_gym.grasp.internal_forces import (
    Cone,
    InfeasibleGraspError,
    InternalForceResult,
    InternalForceSettings,
    InternalForceSolver,
    friction_cone_residual,
    sliding_direction,
    solve_internal_forces,
    solve_lp,
    solve_socp,
)
from ias_gym.grasp.wrench_matrix import wrench_matrix

# docs/NOTES.md "Reference LP result": the paper's pen in SI units.
MU = 0.25  # [-]
RADIUS = 0.01  # [m]
F0 = 0.1  # [N]
GRAVITY = np.array([0.0, -1.0, 0.0, 0.0, 0.0, 0.0])  # w_g of eq. (18), m g = 1 N
PHI = np.array([0.03, 0.02, 0.02, 0.03])  # [m]
OUTWARD = (-1.0, -1.0, 1.0, 1.0)  # eq. (17): fingers 1, 2 slide to -x, fingers 3, 4 to +x
PEN = InternalForceSettings(mu=MU, f0=F0)
PEN_EXACT = InternalForceSettings(mu=MU, f0=F0, cone="exact")

Solve = Callable[..., InternalForceResult]


def pen_w(phi: np.ndarray = PHI) -> np.ndarray:
    """W of eq. (16): docs/NOTES.md contact points, normals into the pen, t1 = +x, t2 = +z."""
    x = phi * np.array(OUTWARD)
    y = RADIUS * np.array([1.0, -1.0, -1.0, 1.0])
    points = np.stack([x, y, np.zeros(4)], axis=1)
    frames = [[(0.0, -yi / RADIUS, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)] for yi in y]
    return wrench_matrix(points, frames)


def phase(k: int) -> dict[int, np.ndarray]:
    """Phase k+1 of eq. (17): only finger k (0-based) slides, outward."""
    return {k: np.array([OUTWARD[k], 0.0])}


def fast_solve(
    W: np.ndarray,
    w_ext: np.ndarray,
    sliding: Mapping[int, np.ndarray] | None = None,
    settings: InternalForceSettings = PEN,
) -> InternalForceResult:
    """A fresh fast-path solver (the warm path has its own tests)."""
    return InternalForceSolver(np.shape(W)[1] // 3, settings).solve(W, w_ext, sliding)


SOLVERS: dict[str, tuple[Solve, InternalForceSettings, Cone]] = {
    "lp": (solve_lp, PEN, "box"),
    "socp": (solve_socp, PEN_EXACT, "exact"),
    "fast": (fast_solve, PEN, "box"),
}


def equilibrium_error(W: np.ndarray, c: np.ndarray, w_ext: np.ndarray, length: float) -> float:
    """max |W c + w_ext| [N], moments divided by a characteristic length [m] (docs/NOTES.md)."""
    residual = W @ c + w_ext
    return float(np.abs(np.concatenate([residual[:3], residual[3:] / length])).max())


def assert_satisfies_constraints(
    res: InternalForceResult,
    W: np.ndarray,
    w_ext: np.ndarray,
    sliding: Mapping[int, np.ndarray],
    s: InternalForceSettings,
    length: float = RADIUS,
    tol: float = 1e-7,
) -> None:
    """Equilibrium, c_n >= f0, sticking cones (with the margin), sliding on the true cone."""
    scale = max(1.0, float(np.abs(res.c).max()))
    assert equilibrium_error(W, res.c, w_ext, length) <= tol * scale
    assert np.all(res.normal >= s.f0 - tol * scale)
    residual = friction_cone_residual(res.c, s.mu_sticking, s.cone)
    for j in range(len(res.normal)):
        if j not in sliding:
            assert residual[j] <= tol * scale, f"contact {j} outside its cone"
        elif s.sliding == "equality":
            np.testing.assert_allclose(
                res.tangential[j], s.mu * res.normal[j] * np.asarray(sliding[j]), atol=tol * scale
            )
    weights = np.ones(len(res.normal)) if s.weights is None else np.asarray(s.weights)
    assert res.objective == pytest.approx(float(weights @ res.normal))


# --- the docs/NOTES.md reference result ---------------------------------------------------------


def test_pen_geometry_reproduces_eq_16() -> None:
    eq_16 = eq16(PHI, RADIUS)
    np.testing.assert_allclose(pen_w(), eq_16, atol=1e-15)


@pytest.mark.parametrize("k", range(4))
@pytest.mark.parametrize("name", SOLVERS)
def test_pen_reference_optimum_is_1_4_newton_in_every_phase(name: str, k: int) -> None:
    solve, s, _ = SOLVERS[name]
    res = solve(pen_w(), GRAVITY, phase(k), s)
    assert res.objective == pytest.approx(1.4, abs=1e-7)
    assert res.normal.sum() == pytest.approx(1.4, abs=1e-7)
    assert_satisfies_constraints(res, pen_w(), GRAVITY, phase(k), s)


@pytest.mark.parametrize("k", range(4))
@pytest.mark.parametrize("name", SOLVERS)
def test_sliding_finger_sits_on_the_cone_in_its_sliding_direction(name: str, k: int) -> None:
    solve, s, _ = SOLVERS[name]
    res = solve(pen_w(), GRAVITY, phase(k), s)
    c_n, (c_t1, c_t2) = res.normal[k], res.tangential[k]
    assert c_t1 == pytest.approx(MU * c_n * OUTWARD[k], abs=1e-8)
    assert c_t2 == pytest.approx(0.0, abs=1e-8)
    assert np.sign(c_t1) == OUTWARD[k]  # the finger drags the pen the way it moves


def test_wrong_gravity_sign_is_feasible_but_fails_the_equilibrium_check() -> None:
    W = pen_w()
    wrong = solve_lp(W, -GRAVITY, phase(0), PEN)  # W c = +w_g: the grasp pushes the pen down
    assert equilibrium_error(W, wrong.c, -GRAVITY, RADIUS) < 1e-9  # consistent with itself
    assert equilibrium_error(W, wrong.c, GRAVITY, RADIUS) == pytest.approx(2.0)  # 2 m g off
    right = solve_lp(W, GRAVITY, phase(0), PEN)
    assert equilibrium_error(W, right.c, GRAVITY, RADIUS) < 1e-9
    assert (W @ right.c)[1] == pytest.approx(1.0)  # the fingers lift the pen


def test_dispatcher_picks_the_solver_from_the_cone() -> None:
    assert solve_internal_forces(pen_w(), GRAVITY, phase(1), PEN).solver == "highs"
    assert solve_internal_forces(pen_w(), GRAVITY, phase(1), PEN_EXACT).solver == "clarabel"


# --- cones, margin, the paper-literal option ------------------------------------------------


@pytest.mark.parametrize("name", SOLVERS)
def test_margin_keeps_sticking_contacts_strictly_inside_the_true_cone(name: str) -> None:
    solve, base, cone = SOLVERS[name]
    margin = 0.2
    s = InternalForceSettings(mu=MU, f0=F0, cone=base.cone, margin=margin)
    for k in range(4):
        res = solve(pen_w(), GRAVITY, phase(k), s)
        assert_satisfies_constraints(res, pen_w(), GRAVITY, phase(k), s)
        true_residual = friction_cone_residual(res.c, MU, cone)
        for j in range(4):
            if j != k:  # sticking: at least margin * mu * c_n inside the true cone
                assert true_residual[j] <= -margin * MU * res.normal[j] + 1e-8
        # the sliding finger uses the true (kinetic) mu
        assert res.tangential[k, 0] == pytest.approx(MU * res.normal[k] * OUTWARD[k], abs=1e-8)


def test_exact_cone_is_tighter_than_the_box() -> None:
    """Two fingers squeeze along y under an equal x and z load: the box's corner is used.

    Moment balance makes both tangential forces (0.125, 0.125) N; the box needs
    c_n >= 0.125 / mu, the cone c_n >= 0.1768 / mu: objectives 2 N and 1 + sqrt(2) N.
    """
    points = [(0.0, RADIUS, 0.0), (0.0, -RADIUS, 0.0)]
    frames = [[(0, -1, 0), (1, 0, 0), (0, 0, 1)], [(0, 1, 0), (1, 0, 0), (0, 0, 1)]]
    W = wrench_matrix(points, frames)
    w_ext = np.array([-0.25, -1.0, -0.25, 0.0, 0.0, 0.0])
    box = solve_lp(W, w_ext, None, PEN)
    exact = solve_socp(W, w_ext, None, PEN_EXACT)
    assert_satisfies_constraints(box, W, w_ext, {}, PEN)
    assert_satisfies_constraints(exact, W, w_ext, {}, PEN_EXACT)
    assert box.objective == pytest.approx(2.0)
    assert exact.objective == pytest.approx(1.0 + np.sqrt(2.0), rel=1e-7)
    assert friction_cone_residual(box.c, MU, "exact").max() > 0.05  # the box leaves the cone
    assert friction_cone_residual(exact.c, MU, "exact").max() <= 1e-8


def test_paper_literal_sliding_admits_forces_beyond_the_cone() -> None:
    """Eq. (20) read literally (docs/NOTES.md saw 13 mu c_n); the equality stays on the cone."""
    W = pen_w()
    paper = InternalForceSettings(mu=MU, f0=F0, sliding="paper")
    ratios = []
    for k in range(4):
        lit = solve_lp(W, GRAVITY, phase(k), paper)
        assert_satisfies_constraints(lit, W, GRAVITY, phase(k), paper)
        assert OUTWARD[k] * lit.tangential[k, 0] >= MU * lit.normal[k] - 1e-9  # eq. (20)
        ratios.append(np.abs(lit.tangential[k]).max() / lit.normal[k])
    assert max(ratios) > 1.1 * MU
    eq = solve_lp(W, GRAVITY, phase(0), PEN)
    assert np.abs(eq.tangential[0]).max() / eq.normal[0] == pytest.approx(MU)


# --- infeasible problems ----------------------------------------------------------------------


@pytest.mark.parametrize("name", SOLVERS)
def test_lateral_load_without_friction_is_infeasible(name: str) -> None:
    solve, base, _ = SOLVERS[name]
    s = InternalForceSettings(mu=0.0, f0=F0, cone=base.cone)
    w_ext = GRAVITY + np.array([0.0, 0.0, 0.3, 0.0, 0.0, 0.0])
    with pytest.raises(InfeasibleGraspError) as err:
        solve(pen_w(), w_ext, phase(1), s)
    message = str(err.value)
    for part in ("equilibrium", "f0=0.1", "mu=0", "0 sticking", "1 sliding s=(-1,0)", "3 sticking"):
        assert part in message


def two_finger_pinch() -> np.ndarray:
    """Two fingers squeezing a sphere along x: rank W = 5 (no moment about the x axis)."""
    points = [(-0.02, 0.0, 0.0), (0.02, 0.0, 0.0)]
    frames = [[(1, 0, 0), (0, 1, 0), (0, 0, 1)], [(-1, 0, 0), (0, 1, 0), (0, 0, 1)]]
    return wrench_matrix(points, frames)


@pytest.mark.parametrize("name", SOLVERS)
def test_degenerate_pinch_holds_weight_but_not_a_twist_about_its_axis(name: str) -> None:
    solve, base, _ = SOLVERS[name]
    s = InternalForceSettings(mu=0.5, f0=F0, cone=base.cone)
    W = two_finger_pinch()
    res = solve(W, GRAVITY, None, s)
    assert_satisfies_constraints(res, W, GRAVITY, {}, s, length=0.02)
    assert res.objective == pytest.approx(2.0, rel=1e-6)  # 2 mu c_n = m g
    with pytest.raises(InfeasibleGraspError, match=r"0 sticking, 1 sticking"):
        solve(W, GRAVITY + np.array([0, 0, 0, 0.01, 0, 0]), None, s)


@pytest.mark.parametrize("name", SOLVERS)
def test_edge_of_feasibility_found_by_hypothesis_is_reported_infeasible(name: str) -> None:
    """Three orthogonal contacts at mu = 0.5: only c = 0 balances the normals, so no torque.

    HiGHS reports "numerical difficulties" here; solve_lp then asks Clarabel.
    """
    radius, tilt = 0.03125, 2e-9  # [m]; tilt: a tangent's drawn angle left this much
    points = radius * np.array([(0, -1, 0), (tilt, 0, 1), (-1, 0, 0)])
    frames = np.array(
        [
            [(0, 1, 0), (0, 0, -1), (-1, 0, 0)],
            [(-tilt, 0, -1), (1, 0, -tilt), (0, -1, 0)],
            [(1, 0, 0), (0, 0, 1), (0, -1, 0)],
        ]
    )
    solve, base, _ = SOLVERS[name]
    s = InternalForceSettings(mu=0.5, f0=0.0, cone=base.cone)
    with pytest.raises(InfeasibleGraspError):
        solve(wrench_matrix(points, frames), np.array([0, 0, 0, 0, 0, -radius]), None, s)


def test_fast_solver_recovers_after_an_infeasible_problem() -> None:
    """Without friction nothing holds a lateral push; the workspace must start afresh."""
    solver = InternalForceSolver(4, InternalForceSettings(mu=0.0, f0=F0))
    first = solver.solve(pen_w(), GRAVITY, phase(0))
    with pytest.raises(InfeasibleGraspError):
        solver.solve(pen_w(), GRAVITY + np.array([0, 0, 0.1, 0, 0, 0]), phase(0))
    again = solver.solve(pen_w(), GRAVITY, phase(0))
    np.testing.assert_allclose(again.c, first.c, atol=1e-9)


# --- the fast path --------------------------------------------------------------------------


def test_fast_path_warm_solutions_equal_cold_ones_along_the_slide() -> None:
    """The regularised QP has a unique optimum: warm starts cannot change the answer."""
    warm = InternalForceSolver(4, PEN)
    for t in np.linspace(0.0, 3.99, 25):
        k = int(t)
        phi = PHI + 0.01 * np.clip(t - np.arange(4), 0.0, 1.0)
        W = pen_w(phi)
        got = warm.solve(W, GRAVITY, phase(k))
        cold = InternalForceSolver(4, PEN).solve(W, GRAVITY, phase(k))
        np.testing.assert_allclose(got.c, cold.c, atol=1e-8)
        assert got.objective == pytest.approx(solve_lp(W, GRAVITY, phase(k), PEN).objective)


def test_weights_weigh_the_normal_forces() -> None:
    W = pen_w()
    weights = (1.0, 3.0, 1.0, 0.5)
    plain = solve_lp(W, GRAVITY, phase(2), PEN)
    s = InternalForceSettings(mu=MU, f0=F0, weights=weights)
    for solve in (solve_lp, fast_solve):
        weighted = solve(W, GRAVITY, phase(2), s)
        assert_satisfies_constraints(weighted, W, GRAVITY, phase(2), s)
        assert weighted.objective <= np.dot(weights, plain.normal) + 1e-9


# --- random grasps ----------------------------------------------------------------------------

unit = st.floats(-1.0, 1.0)
direction = st.tuples(unit, unit, unit).filter(lambda v: 0.2 < np.linalg.norm(v))


@st.composite
def grasps(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, dict[int, np.ndarray], float]:
    """3-4 contacts on a sphere, inward normals, random tangents; a small load; one may slide."""
    radius = draw(st.floats(0.01, 0.05))  # [m]
    m = draw(st.integers(3, 4))
    points, frames = [], []
    for _ in range(m):
        p = np.array(draw(direction))
        p /= np.linalg.norm(p)
        a = draw(st.floats(0.0, 2 * np.pi))
        n = -p
        e = np.eye(3)[int(np.argmin(np.abs(n)))]
        u = np.cross(n, e) / np.linalg.norm(np.cross(n, e))
        t1 = np.cos(a) * u + np.sin(a) * np.cross(n, u)
        points.append(radius * p)
        frames.append([n, t1, np.cross(n, t1)])
    W = wrench_matrix(points, frames)
    # Non-degenerate: every wrench is reachable, moments with levers of 1 % of the radius.
    levers = np.array([1, 1, 1, radius, radius, radius])[:, None]
    assume(np.linalg.svd(W / levers, compute_uv=False)[-1] > 1e-2)
    force = np.array(draw(st.tuples(unit, unit, unit)))  # [N]
    moment = radius * np.array(draw(st.tuples(unit, unit, unit)))  # [N m]
    sliding = {}
    if draw(st.booleans()):
        b = draw(st.floats(0.0, 2 * np.pi))
        sliding[draw(st.integers(0, m - 1))] = np.array([np.cos(b), np.sin(b)])
    return W, np.concatenate([force, moment]), sliding, radius


def solve_or_none(solve: Solve, *args: object) -> InternalForceResult | None:
    try:
        return solve(*args)
    except InfeasibleGraspError:
        return None


def verdict_flips(
    solve: Solve,
    W: np.ndarray,
    w_ext: np.ndarray,
    sliding: dict[int, np.ndarray],
    s: InternalForceSettings,
) -> bool:
    """Whether feasibility flips within +-0.1 % of mu: the problem is at the edge.

    Hypothesis loves symmetric grasps at round mu (three orthogonal contacts at mu = 0.5 or
    1) where only the limit of ever larger forces balances the normals; there the verdict
    belongs to the solvers' tolerances.
    """
    verdicts = {
        solve_or_none(solve, W, w_ext, sliding, replace(s, mu=s.mu * f)) is None
        for f in (0.999, 1.001)
    }
    return len(verdicts) > 1


def feasible(solve: Solve, *args: object) -> bool:
    """Whether ``solve`` finds a solution (giving up counts as not finding one)."""
    try:
        return solve_or_none(solve, *args) is not None
    except RuntimeError:
        return False


def solve_or_edge(
    solve: Solve,
    W: np.ndarray,
    w_ext: np.ndarray,
    sliding: dict[int, np.ndarray],
    s: InternalForceSettings,
) -> InternalForceResult | None:
    """The solution, or None if infeasible; a solver may give up only at the edge: where the
    verdict flips within +-0.1 % of mu, or where no neighbour is feasible either. The latter
    is a weakly infeasible problem (infeasible, but at zero distance from feasibility: only
    ever larger forces come near a balance), whose infeasibility has no certificate for an
    interior-point solver to find; Clarabel reports a numerical error there, depending on
    the last bits (seen: three contacts at right angles, one sliding, at mu = 1.0)."""
    try:
        return solve_or_none(solve, W, w_ext, sliding, s)
    except RuntimeError:
        assert verdict_flips(solve, W, w_ext, sliding, s) or not any(
            feasible(solve, W, w_ext, sliding, replace(s, mu=s.mu * f)) for f in (0.999, 1.001)
        )
        assume(False)
        return None


@settings(max_examples=300, deadline=None)
@given(
    grasp=grasps(),
    mu=st.floats(0.3, 1.0),
    f0=st.floats(0.05, 0.5),  # f0 > 0 keeps every contact off the cone apex (eq. 19)
    margin=st.sampled_from([0.0, 0.1]),
)
def test_random_grasps_solutions_satisfy_every_constraint(
    grasp: tuple[np.ndarray, np.ndarray, dict[int, np.ndarray], float],
    mu: float,
    f0: float,
    margin: float,
) -> None:
    W, w_ext, sliding, radius = grasp
    box = InternalForceSettings(mu=mu, f0=f0, margin=margin)
    exact = InternalForceSettings(mu=mu, f0=f0, margin=margin, cone="exact")
    lp = solve_or_edge(solve_lp, W, w_ext, sliding, box)
    fast = solve_or_edge(fast_solve, W, w_ext, sliding, box)
    socp = solve_or_edge(solve_socp, W, w_ext, sliding, exact)
    # Whatever a solver returns satisfies every constraint.
    for res, s, tol in ((lp, box, 1e-7), (fast, box, 1e-7), (socp, exact, 1e-6)):
        if res is not None:
            assert_satisfies_constraints(res, W, w_ext, sliding, s, radius, tol)
    # Away from the edge, and from grasps that need kN for a 1 N load (a solver may accept
    # 1e6 N forces cancelling to 1e-10 N where the problem is feasible only in the limit),
    # the solvers agree.
    assume(not verdict_flips(solve_lp, W, w_ext, sliding, box))
    assume(all(res is None or res.objective < 1e3 for res in (lp, fast, socp)))
    event(f"box {'infeasible' if lp is None else 'feasible'}, {len(sliding)} sliding")
    assert (lp is None) == (fast is None), "LP and fast path disagree on feasibility"
    if lp is not None and fast is not None:
        # HiGHS holds constraints to 1e-7 N absolute; ill-conditioned grasps need 100s of N.
        assert fast.objective == pytest.approx(lp.objective, rel=1e-6, abs=1e-9)
    if socp is not None:
        assert lp is not None, "exact cone feasible but the larger box infeasible"
        assert socp.objective >= lp.objective - 1e-6 * max(1.0, lp.objective)


# --- inputs and helpers -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("W", "w_ext", "sliding", "match"),
    [
        (np.zeros((6, 10)), GRAVITY, None, "6 x 3m"),
        (np.zeros((5, 12)), GRAVITY, None, "6 x 3m"),
        (np.full((6, 12), np.nan), GRAVITY, None, "finite"),
        (pen_w(), GRAVITY[:3], None, "6-vector"),
        (pen_w(), np.array([0, np.inf, 0, 0, 0, 0]), None, "finite"),
        (pen_w(), GRAVITY, {4: (1.0, 0.0)}, r"not one of 0\.\.3"),
        (pen_w(), GRAVITY, {0: (2.0, 0.0)}, "unit vector"),
        (pen_w(), GRAVITY, {0: (1.0, 0.0, 0.0)}, "2-vector"),
    ],
)
@pytest.mark.parametrize("name", SOLVERS)
def test_bad_inputs_raise_value_error(
    name: str, W: np.ndarray, w_ext: np.ndarray, sliding: dict | None, match: str
) -> None:
    solve, s, _ = SOLVERS[name]
    with pytest.raises(ValueError, match=match) as err:
        solve(W, w_ext, sliding, s)
    assert not isinstance(err.value, InfeasibleGraspError)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"mu": -0.1},
        {"f0": np.nan},
        {"cone": "cubic"},
        {"margin": 1.0},
        {"sliding": "lit"},
        {"weights": (1.0, 0.0)},
    ],
)
def test_bad_settings_raise_value_error(kwargs: dict[str, object]) -> None:
    with pytest.raises(ValueError):
        InternalForceSettings(**kwargs)  # type: ignore[arg-type]


def test_solvers_refuse_the_other_cone_and_wrong_sizes() -> None:
    with pytest.raises(ValueError, match=r"settings\.cone"):
        solve_lp(pen_w(), GRAVITY, None, PEN_EXACT)
    with pytest.raises(ValueError, match=r"settings\.cone"):
        solve_socp(pen_w(), GRAVITY, None, PEN)
    with pytest.raises(ValueError, match=r"settings\.cone"):
        InternalForceSolver(4, PEN_EXACT)
    with pytest.raises(ValueError, match="contacts"):
        InternalForceSolver(3, PEN).solve(pen_w(), GRAVITY)
    with pytest.raises(ValueError, match="weights"):
        solve_lp(pen_w(), GRAVITY, None, InternalForceSettings(weights=(1.0, 1.0)))


def test_result_is_read_only() -> None:
    res = solve_lp(pen_w(), GRAVITY, phase(0), PEN)
    with pytest.raises(ValueError):
        res.c[0] = 5.0


def test_friction_cone_residual_box_and_exact() -> None:
    c = np.array([1.0, 0.3, 0.4, 2.0, 0.0, 0.0])
    np.testing.assert_allclose(friction_cone_residual(c, 0.5, "box"), [-0.1, -1.0])
    np.testing.assert_allclose(friction_cone_residual(c, 0.5, "exact"), [0.0, -1.0], atol=1e-15)


def test_sliding_direction_is_the_unit_relative_velocity() -> None:
    np.testing.assert_allclose(sliding_direction([-0.003, 0.0]), [-1.0, 0.0])
    np.testing.assert_allclose(sliding_direction([3.0, 4.0]), [0.6, 0.8])
    with pytest.raises(ValueError, match="not sliding"):
        sliding_direction([0.0, 0.0])

"""Invariants of the grip transform, eqs. (4)-(15), on the paper's pen and on random grasps."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from paper_reference import eq16

from ias_gym.grasp.grip_transform import (
    GraspRankError,
    GripTransform,
    null_space_basis,
    pseudo_inverse,
)
from ias_gym.grasp.pen_skill import pen_wrench_matrix
from ias_gym.grasp.wrench_matrix import contact_wrench_basis, wrench_matrix

PEN_W = pen_wrench_matrix([0.03, 0.02, 0.02, 0.03])
R = 0.01


def test_pen_wrench_matrix_is_eq16() -> None:
    """docs/NOTES.md's corrected eq. (16), written out entry by entry."""
    np.testing.assert_allclose(PEN_W, eq16(), atol=1e-15)
    s = np.linalg.svd(PEN_W, compute_uv=False)
    np.testing.assert_allclose(s, [2, 2, 2, 0.05477, 0.05099, 0.02], rtol=1e-3)


def _check_invariants(W: np.ndarray, rng: np.random.Generator) -> None:
    n = W.shape[1]
    g = GripTransform.from_wrench_matrix(W)
    scale = np.abs(W).max()
    tol = 1e-9 * scale
    assert np.linalg.matrix_rank(W) == 6
    np.testing.assert_allclose(W @ g.N, 0, atol=tol)
    np.testing.assert_allclose(g.N.T @ g.N, np.eye(n - 6), atol=1e-9)
    np.testing.assert_allclose(W @ g.W_pinv, np.eye(6), atol=1e-9)
    np.testing.assert_allclose(g.G_T, np.hstack([g.W_pinv, g.N]), atol=0)
    np.testing.assert_allclose(g.G_T @ g.G_T_inv, np.eye(n), atol=1e-9)
    np.testing.assert_allclose(np.linalg.inv(g.G), g.G_inv, atol=1e-6 * np.abs(g.G_inv).max())
    np.testing.assert_allclose(g.G_inv, np.hstack([W.T, g.N]), atol=0)
    np.testing.assert_allclose(W @ g.G_T, np.hstack([np.eye(6), np.zeros((6, n - 6))]), atol=1e-9)

    c = rng.normal(size=n)
    c_p, c_h = g.split(c)
    assert abs(c_p @ c_h) < 1e-9 * (c @ c)
    np.testing.assert_allclose(W @ c_h, 0, atol=tol * np.abs(c).max())
    np.testing.assert_allclose(c_p, g.W_pinv @ (W @ c), atol=1e-12)
    F = g.generalized_force(c)
    np.testing.assert_allclose(F[:6], W @ c, atol=1e-12)
    np.testing.assert_allclose(g.intensities(F), c, atol=1e-9)
    np.testing.assert_allclose(c_h, g.N @ g.internal_forces(c), atol=1e-12)

    # Power is preserved: c . d = F . v (eqs. 10-13).
    v = rng.normal(size=n)
    d = g.twist_intensities(v)
    assert c @ d == pytest.approx(F @ v, rel=1e-9, abs=1e-12)
    np.testing.assert_allclose(g.object_velocity(d), v, atol=1e-8)


def test_invariants_on_the_pen() -> None:
    _check_invariants(PEN_W, np.random.default_rng(0))


def _random_grasp(seed: int, n_contacts: int, soft: bool) -> np.ndarray:
    """Contacts on a sphere of random radius, normals pointing to the centre."""
    rng = np.random.default_rng(seed)
    radius = rng.uniform(0.005, 0.2)
    points, frames = [], []
    for _ in range(n_contacts):
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        t1 = np.cross(u, rng.normal(size=3))
        t1 /= np.linalg.norm(t1)
        points.append(radius * u)
        frames.append([-u, t1, np.cross(-u, t1)])
    return wrench_matrix(points, frames, model="soft" if soft else "pcwf")


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    n_contacts=st.integers(3, 6),
    soft=st.booleans(),
)
def test_invariants_on_random_grasps(seed: int, n_contacts: int, soft: bool) -> None:
    W = _random_grasp(seed, n_contacts, soft)
    s = np.linalg.svd(W, compute_uv=False)
    if s[-1] < 1e-6 * s[0]:  # a degenerate draw (e.g. collinear contacts) is not this test
        return
    _check_invariants(W, np.random.default_rng(seed))


def test_contact_models_column_counts() -> None:
    frame = ([0, 0, -1], [1, 0, 0], [0, 1, 0])
    assert contact_wrench_basis([0, 0, 1], *frame, model="frictionless").shape == (6, 1)
    assert contact_wrench_basis([0, 0, 1], *frame, model="pcwf").shape == (6, 3)
    soft = contact_wrench_basis([0, 0, 1], *frame, model="soft")
    np.testing.assert_allclose(soft[:, 3], [0, 0, 0, 0, 0, -1])
    with pytest.raises(ValueError, match="tangents"):
        contact_wrench_basis([0, 0, 1], [0, 0, -1], model="pcwf")


def test_rank_deficient_grasp_states_the_rank() -> None:
    # Two hard-finger contacts: 6 columns but the pair cannot resist torsion about their line.
    W = wrench_matrix(
        [[0, 0, 0.01], [0, 0, -0.01]],
        [[[0, 0, -1], [1, 0, 0], [0, 1, 0]], [[0, 0, 1], [1, 0, 0], [0, 1, 0]]],
    )
    with pytest.raises(GraspRankError, match="rank W = 5"):
        GripTransform.from_wrench_matrix(W)
    with pytest.raises(GraspRankError, match="rank W = 5"):
        pseudo_inverse(W)
    with pytest.raises(ValueError, match="6 x n"):
        pseudo_inverse(np.zeros((5, 12)))
    with pytest.raises(ValueError, match="NaN"):
        pseudo_inverse(np.full((6, 12), np.nan))


def test_null_space_follows_the_previous_basis() -> None:
    """Along the sliding trajectory N(t) must be continuous, not re-drawn by each SVD."""
    phis = np.linspace(0.03, 0.04, 101)
    prev = None
    jumps = []
    for phi in phis:
        N = null_space_basis(pen_wrench_matrix([phi, 0.02, 0.02, 0.03]), prev)
        if prev is not None:
            jumps.append(np.abs(N - prev).max())
        prev = N
    assert max(jumps) < 0.05
    # Without the previous basis any orthonormal basis is valid; only the subspace is fixed.
    N0 = null_space_basis(PEN_W)
    np.testing.assert_allclose(N0 @ N0.T, prev_projector(PEN_W), atol=1e-9)


def prev_projector(W: np.ndarray) -> np.ndarray:
    return np.eye(W.shape[1]) - W.T @ np.linalg.solve(W @ W.T, W)


@pytest.mark.parametrize("model", ["frictionless", "pcwf", "soft"])
def test_wrench_matrix_stacks_the_contact_bases(model: str) -> None:
    """The vectorised W equals the per-contact bases side by side, about any reference."""
    rng = np.random.default_rng(3)
    points, frames, ref = rng.normal(size=(4, 3)), rng.normal(size=(4, 3, 3)), rng.normal(size=3)
    bases = [
        contact_wrench_basis(p, *f, model=model, reference=ref)
        for p, f in zip(points, frames, strict=True)
    ]
    expected = np.concatenate(bases, axis=1)
    np.testing.assert_allclose(wrench_matrix(points, frames, model, ref), expected, atol=1e-15)
    assert wrench_matrix(np.zeros((0, 3)), np.zeros((0, 3, 3))).shape == (6, 0)
    with pytest.raises(ValueError, match="contact points"):
        wrench_matrix(points, frames[:3])

"""The terms of Theorem 1 (ias_gym.baselines.law) on synthetic grasps; one check of the adapter.

A synthetic grasp: four point contacts with friction on a cylinder along x (normals into the
cylinder, t1 along its axis), W from :func:`ias_gym.grasp.wrench_matrix.wrench_matrix`, a random
block-diagonal fingertip Jacobian J (one well-conditioned 3 x 3 block per finger) and a random
symmetric positive definite joint inertia M. Each test states the equation it checks and
computes the expected value another way than the law does.
"""

from __future__ import annotations

import ast
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ias_gym  # noqa: F401  (registers the envs)
from ias_gym.baselines import law
from ias_gym.baselines.grip_transform_control import GripTransformController
from ias_gym.baselines.grip_transform_terms import approach_torques, motion_share, right_inverses
from ias_gym.envs.pen_hand_env import PenHandEnv
from ias_gym.grasp.grip_transform import GraspRankError, null_space_basis, pseudo_inverse
from ias_gym.grasp.internal_forces import InternalForceSettings, friction_cone_residual
from ias_gym.grasp.wrench_matrix import cross3, wrench_matrix

K = 4  # fingers
SEEDS = st.integers(0, 2**31 - 1)


class Motion:
    """A plain object state / reference (what the env's PenState and PenReference provide)."""

    def __init__(self, rng: np.random.Generator) -> None:
        axis = rng.normal(size=3)
        self.position = rng.normal(scale=0.01, size=3)
        self.velocity = rng.normal(scale=0.1, size=3)
        self.acceleration = rng.normal(size=3)
        self.axis = axis / np.linalg.norm(axis)
        self.omega = rng.normal(size=3)
        self.alpha = rng.normal(size=3)


def cylinder_grasp(rng: np.random.Generator) -> np.ndarray:
    """W (6 x 12) of four contacts at random places on a cylinder along x."""
    radius = rng.uniform(0.003, 0.02)
    x = rng.uniform(-0.05, 0.05, size=K)
    theta = rng.uniform(0, 2 * np.pi, size=K)
    radial = np.column_stack([np.zeros(K), np.cos(theta), np.sin(theta)])
    points = np.column_stack([x, np.zeros(K), np.zeros(K)]) + radius * radial
    normal = -radial  # the finger pushes into the cylinder
    t1 = np.tile([1.0, 0.0, 0.0], (K, 1))
    t2 = np.cross(t1, normal)
    frames = np.stack([normal, t1, t2], axis=1)
    return wrench_matrix(points, frames)


def block_jacobian(rng: np.random.Generator) -> np.ndarray:
    """A 12 x 12 block-diagonal J whose 3 x 3 blocks have condition numbers below 100."""
    J = np.zeros((3 * K, 3 * K))
    for k in range(K):
        while True:
            block = rng.normal(scale=0.03, size=(3, 3))
            if np.linalg.cond(block) < 100:
                break
        J[3 * k : 3 * k + 3, 3 * k : 3 * k + 3] = block
    return J


def spd(rng: np.random.Generator, n: int, scale: float) -> np.ndarray:
    a = rng.normal(scale=scale, size=(n, n))
    return a @ a.T + scale**2 * np.eye(n)


# ---------------------------------------------------------------- eqs. (41), (43)
@settings(max_examples=60, deadline=None)
@given(seed=SEEDS)
def test_object_acceleration_is_pd_with_feedforward_and_leaves_roll_free(seed: int) -> None:
    """Eqs. (41), (43): a_d = r''_d - Kv e_v - Kp e_p; the axis error turns the axis toward
    the reference's; spinning about the object's own axis changes nothing."""
    rng = np.random.default_rng(seed)
    gains = {"kp": 400.0, "kv": 40.0, "kp_rot": 300.0, "kv_rot": 30.0}
    ref, state = Motion(rng), Motion(rng)
    a_d = law.object_acceleration(state, ref, **gains)

    expected = (
        ref.acceleration
        - gains["kp"] * (state.position - ref.position)
        - gains["kv"] * (state.velocity - ref.velocity)
    )
    np.testing.assert_allclose(a_d[:3], expected, rtol=1e-12, atol=1e-12)

    # Roll free: the part of omega along the axis is not fed back.
    state_spun = Motion(np.random.default_rng(0))
    state_spun.__dict__.update(state.__dict__)
    state_spun.omega = state.omega + rng.normal(scale=10.0) * state.axis
    spun = law.object_acceleration(state_spun, ref, **gains)
    np.testing.assert_allclose(spun, a_d, rtol=1e-9, atol=1e-9)

    # With the twist on the reference, only the axis error acts; it turns the axis toward
    # the reference's axis (d axis/dt = alpha x axis has a positive component along it).
    state_still = Motion(np.random.default_rng(0))
    state_still.__dict__.update(state.__dict__)
    state_still.omega = ref.omega - (ref.omega @ state.axis) * state.axis
    ref.omega = state_still.omega
    alpha_error = law.object_acceleration(state_still, ref, **gains)[3:] - ref.alpha
    np.testing.assert_allclose(
        alpha_error, gains["kp_rot"] * np.cross(state.axis, ref.axis), rtol=1e-9, atol=1e-9
    )
    if abs(state.axis @ ref.axis) < 0.99:
        assert np.cross(alpha_error, state.axis) @ ref.axis > 0


# ---------------------------------------------------------------- eq. (33)
@settings(max_examples=60, deadline=None)
@given(seed=SEEDS)
def test_object_wrench_inverts_newton_euler(seed: int) -> None:
    """Eq. (33) plus the weight: Newton-Euler under the returned wrench and gravity gives a_d."""
    rng = np.random.default_rng(seed)
    mass = rng.uniform(0.001, 1.0)
    inertia = spd(rng, 3, 1e-3)
    omega, a_d = rng.normal(size=3) * 5, rng.normal(size=6)
    gravity = rng.normal(size=3) * 10
    w = law.object_wrench(mass, inertia, omega, a_d, gravity)
    # Forward dynamics, written independently: m a = f + m g; I alpha + omega x I omega = n.
    acc = (w[:3] + mass * gravity) / mass
    alpha = np.linalg.solve(inertia, w[3:] - np.cross(omega, inertia @ omega))
    np.testing.assert_allclose(acc, a_d[:3], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(alpha, a_d[3:], rtol=1e-7, atol=1e-7)


def test_object_wrench_holds_a_still_pen_against_paper_gravity() -> None:
    """At rest in the paper frame (y up) the contacts carry the weight, m g, upward."""
    w = law.object_wrench(0.02, np.eye(3) * 1e-6, np.zeros(3), np.zeros(6), np.array([0, -9.81, 0]))
    np.testing.assert_array_equal(w, [0.0, 0.02 * 9.81, 0.0, 0.0, 0.0, 0.0])


# ---------------------------------------------------------------- eq. (44)
@settings(max_examples=60, deadline=None)
@given(seed=SEEDS, delta=st.floats(1.0, 100.0), dt=st.floats(1e-4, 0.02))
def test_internal_force_step_is_one_euler_step_of_eq_44(seed: int, delta: float, dt: float) -> None:
    """With W' = 0 the error shrinks by (1 - delta dt); with W' it follows
    e_f' = -(delta I + W+ W') e_f for one step."""
    rng = np.random.default_rng(seed)
    W = cylinder_grasp(rng)
    W_pinv = pseudo_inverse(W, least_squares_if_singular=True)
    e_f = law.internal_part(rng.normal(size=3 * K), W, W_pinv)
    np.testing.assert_allclose(W @ e_f, 0.0, atol=1e-9)  # an internal-force error

    still = law.internal_force_step(e_f, W_pinv, np.zeros_like(W), delta, dt)
    np.testing.assert_allclose(still, (1.0 - delta * dt) * e_f, rtol=1e-12, atol=1e-15)

    dW = rng.normal(size=W.shape)
    rate = -(delta * np.eye(3 * K) + W_pinv @ dW)  # the matrix of eq. (44)
    moving = law.internal_force_step(e_f, W_pinv, dW, delta, dt)
    np.testing.assert_allclose(moving, e_f + dt * rate @ e_f, rtol=1e-10, atol=1e-12)


# ---------------------------------------------------------------- the cone limiter
def _feasible(
    c: np.ndarray, active: np.ndarray, sliding: set[int], s: InternalForceSettings, tol: float
) -> bool:
    """The internal-force problem's constraints, checked through the solver's own residual."""
    per = c.reshape(-1, 3)
    for k in np.flatnonzero(active):
        if per[k, 0] < s.f0 - tol:
            return False
        if k not in sliding and friction_cone_residual(per[k], s.mu_sticking, s.cone)[0] > tol:
            return False
    return True


@settings(max_examples=150, deadline=None)
@given(seed=SEEDS, cone=st.sampled_from(["box", "polygon"]))
def test_cone_limiter_keeps_every_constraint_and_is_maximal(seed: int, cone: str) -> None:
    """The returned fraction keeps c_ref + lam step feasible; lam + 1e-6 is not; lam = 1
    whenever the whole step is feasible. Inactive contacts (arbitrary values) and the
    friction of sliding contacts do not count."""
    rng = np.random.default_rng(seed)
    s = InternalForceSettings(mu=0.25, f0=0.2, margin=0.4, cone=cone)  # type: ignore[arg-type]
    active = rng.random(K) < 0.8
    sliding = {int(k) for k in np.flatnonzero(rng.random(K) < 0.3)}
    normal = s.f0 + rng.uniform(0.0, 2.0, size=K)
    # A tangential force strictly inside the cone's inscribed circle (the polygon's is
    # cos(pi/8) mu c_n, the box's mu c_n), for every contact ...
    radius = (0.92 if cone == "polygon" else 1.0) * s.mu_sticking * normal
    angle = rng.uniform(0, 2 * np.pi, size=K)
    tangential = (rng.uniform(0, 0.999, size=K) * radius)[:, None] * np.column_stack(
        [np.cos(angle), np.sin(angle)]
    )
    c_ref = np.column_stack([normal, tangential])
    # ... but sliding contacts may be anywhere on their cone and inactive ones anything.
    for k in sliding:
        c_ref[k, 1:] = rng.normal(size=2) * normal[k]
    c_ref[~active] = rng.normal(size=(int((~active).sum()), 3)) * 5
    c_ref = c_ref.reshape(-1)
    assert _feasible(c_ref, active, sliding, s, tol=0.0)

    step = rng.normal(size=3 * K) * 10 ** rng.uniform(-3, 1)
    lam = law.largest_step_inside_cones(c_ref, step, active, sliding, s)
    assert 0.0 <= lam <= 1.0
    assert _feasible(c_ref + lam * step, active, sliding, s, tol=1e-9)
    if _feasible(c_ref + step, active, sliding, s, tol=0.0):
        assert lam == 1.0
    else:
        assert lam < 1.0
        assert not _feasible(c_ref + min(1.0, lam + 1e-6) * step, active, sliding, s, tol=0.0)


def test_cone_limiter_ignores_inactive_and_sliding_friction() -> None:
    """A step that would push an inactive contact anywhere, or a sliding one out of its
    cone, is taken whole; the same step on a sticking contact is cut at its cone."""
    s = InternalForceSettings(mu=0.25, f0=0.2, margin=0.0, cone="box")
    c_ref = np.tile([1.0, 0.0, 0.0], K)
    step = np.zeros(3 * K)
    step[1] = 1.0  # contact 0's t1 by 1 N: its box |c_t1| <= 0.25 N is crossed at 0.25
    everyone = np.ones(K, dtype=bool)
    assert law.largest_step_inside_cones(c_ref, step, everyone, set(), s) == pytest.approx(0.25)
    assert law.largest_step_inside_cones(c_ref, step, everyone, {0}, s) == 1.0
    idle = everyone.copy()
    idle[0] = False
    assert law.largest_step_inside_cones(c_ref, step, idle, set(), s) == 1.0
    step[0] = -2.0  # the normal force of a sliding contact still has its bound f0
    assert law.largest_step_inside_cones(c_ref, step, everyone, {0}, s) == pytest.approx(0.4)


# ---------------------------------------------------------------- eq. (45)
@settings(max_examples=60, deadline=None)
@given(seed=SEEDS)
def test_joint_torques_reproduce_the_commanded_forces_through_J_transpose(seed: int) -> None:
    """Eq. (45) with the M-terms off: tau - H = J^T f, so f is recovered from the torques;
    the M-terms add on top unchanged."""
    rng = np.random.default_rng(seed)
    J = block_jacobian(rng)
    f, H = rng.normal(size=3 * K), rng.normal(size=3 * K) * 0.01
    tau = law.joint_torques(J, f, H)
    np.testing.assert_allclose(np.linalg.solve(J.T, tau - H), f, rtol=1e-8, atol=1e-8)
    inertia, feedforward = rng.normal(size=3 * K), rng.normal(size=3 * K)
    full = law.joint_torques(J, f, H, inertia, feedforward)
    np.testing.assert_allclose(full - inertia - feedforward, tau, rtol=1e-12, atol=1e-14)


@settings(max_examples=60, deadline=None)
@given(seed=SEEDS)
def test_finger_inertia_gives_the_contact_accelerations_of_the_object(seed: int) -> None:
    """Eqs. (32), (39), (45): the joint accelerations M^-1 tau of the finger-inertia term move
    each touching contact with W^T a_d + W'^T v - J' theta'; idle fingers get none."""
    rng = np.random.default_rng(seed)
    W, J, dJ = cylinder_grasp(rng), block_jacobian(rng), block_jacobian(rng) * 10
    dW = rng.normal(size=W.shape)
    M = spd(rng, 3 * K, 0.01)
    qvel, a_d, v = rng.normal(size=3 * K), rng.normal(size=6), rng.normal(size=6)
    active = rng.random(K) < 0.7
    touching = np.repeat(active, 3)
    J_pinv = law.damped_pinv_blocks(J, 0.0)
    tau = law.finger_inertia_torques(M, J_pinv, W, dW, dJ, qvel, a_d, v, touching)

    qacc = np.linalg.solve(M, tau)
    wanted = W.T @ a_d + dW.T @ v - dJ @ qvel
    np.testing.assert_allclose((J @ qacc)[touching], wanted[touching], rtol=1e-7, atol=1e-7)
    np.testing.assert_allclose(qacc[~touching], 0.0, atol=1e-9)


@settings(max_examples=50, deadline=None)
@given(SEEDS)
def test_the_motion_share_is_the_largest_that_the_motors_can_add(seed: int) -> None:
    # Beyond the paper: holding torques first, one share s of the motion terms per env.
    rng = np.random.default_rng(seed)
    limits = rng.uniform(0.1, 1.0, (5, 9))
    hold = rng.uniform(-1.2, 1.2, (5, 9)) * limits  # some joints saturated by holding alone
    motion = rng.normal(scale=0.8, size=(5, 9))
    s = motion_share(hold, motion, limits)
    assert s.shape == (5,) and np.all((s >= 0) & (s <= 1))
    free = np.abs(hold) <= limits
    total = hold + s[:, None] * motion
    assert np.all(np.abs(total[free]) <= limits[free] * (1 + 1e-12))
    # maximal: a little more motion breaks a free joint's limit, unless all of it fits
    more = hold + np.minimum(s + 1e-6, 1.0)[:, None] * motion
    over = (np.abs(more) > limits) & free
    assert np.all(over.any(axis=1) | (s == 1.0))
    # motion that fits is taken whole; a joint saturated by holding alone does not count
    assert motion_share(np.zeros(3), np.array([0.5, -0.5, 0.0]), np.ones(3)) == 1.0
    assert motion_share(np.array([2.0, 0.0]), np.array([1.0, 0.5]), np.ones(2)) == 1.0
    assert motion_share(np.array([0.5, 0.0]), np.array([1.0, 0.0]), np.ones(2)) == 0.5


def test_damped_pinv_blocks_invert_each_finger() -> None:
    """Undamped, blockdiag(J+) is J's inverse; damped, it is eq. (32)'s full-matrix
    ``J^T (J J^T + lambda I)^-1`` of the block-diagonal J."""
    rng = np.random.default_rng(5)
    J = block_jacobian(rng)
    x = rng.normal(size=3 * K)
    np.testing.assert_allclose(J @ law.apply_blocks(law.damped_pinv_blocks(J, 0.0), x), x, 1e-9)
    damped = law.apply_blocks(law.damped_pinv_blocks(J, 1e-5), x)
    full = J.T @ np.linalg.solve(J @ J.T + 1e-5 * np.eye(3 * K), x)
    np.testing.assert_allclose(damped, full, rtol=1e-9, atol=1e-9)
    assert np.abs(J @ damped - x).max() > 1e-6  # the damping did act


@settings(max_examples=40, deadline=None)
@given(seed=SEEDS, speed=st.floats(0.001, 0.1))
def test_an_off_finger_is_paid_to_follow_the_object_and_close_on_it(
    seed: int, speed: float
) -> None:
    """The approach torques of a finger off the object are its joints' damping at the joint
    speeds that move its tip with the object's point under it plus ``speed`` along the
    normal (toward the object); a touching finger gets none. Dry friction alone: the torque
    has the sign of that joint speed and at most the friction's size."""
    rng = np.random.default_rng(seed)
    W, J = cylinder_grasp(rng), block_jacobian(rng)
    twist = rng.normal(scale=0.05, size=6)
    active = rng.random(K) < 0.5
    active[0] = False  # at least one finger off
    off = np.repeat(~active, 3)
    damping = rng.uniform(0.01, 0.3, size=3 * K)
    J_pinv = law.damped_pinv_blocks(J, 0.0)
    zero = np.zeros(3 * K)
    tau = approach_torques(damping, zero, J_pinv, W, twist, off, speed, 0.005)
    tip = J @ (tau / damping)  # the tip velocities the torques pay the damping for
    wanted = W.T @ twist
    wanted[0::3] += speed
    np.testing.assert_allclose(tip[off], wanted[off], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(tau[~off], 0.0)  # block-diagonal J: joints of touching
    closing = tip[0::3] - (W.T @ twist)[0::3]  # the tip's speed toward the object's point
    np.testing.assert_allclose(closing[~active], speed, rtol=1e-9)
    coulomb = rng.uniform(0.01, 0.1, size=3 * K)
    dry = approach_torques(zero, coulomb, J_pinv, W, twist, off, speed, 0.005)
    qvel = law.apply_blocks(J_pinv, np.where(off, wanted, 0.0))
    assert np.all(np.abs(dry) <= coulomb + 1e-15)
    assert np.all(np.sign(dry[off]) == np.sign(qvel[off]))


# ---------------------------------------------------------------- batches of envs
@settings(max_examples=30, deadline=None)
@given(seed=SEEDS)
def test_each_row_of_a_batch_is_that_envs_own_term_bit_for_bit(seed: int) -> None:
    """The adapter computes n envs in one call (a leading env axis): row i of every term must
    be env i's term computed alone, to the last bit (no mixing across envs, and the
    arithmetic must not change with n: a batched expert acts as n serial ones)."""
    rng = np.random.default_rng(seed)
    n = 5
    W = np.stack([cylinder_grasp(rng) for _ in range(n)])
    J = np.stack([block_jacobian(rng) for _ in range(n)])
    dJ, dW = rng.normal(size=J.shape), rng.normal(size=W.shape)
    M = np.stack([spd(rng, 3 * K, 0.01) for _ in range(n)])
    W_pinv = np.stack([pseudo_inverse(w) for w in W])
    c, step = rng.normal(size=(n, 3 * K)), rng.normal(size=(n, 3 * K))
    c[:, 0::3] = np.abs(c[:, 0::3]) + 1.0  # feasible normals
    qvel, a_d, v = rng.normal(size=(n, 3 * K)), rng.normal(size=(n, 6)), rng.normal(size=(n, 6))
    active = rng.random((n, K)) < 0.8
    sliding = rng.random((n, K)) < 0.3
    touching = np.repeat(active, 3, axis=-1)
    settings_ = InternalForceSettings(mu=0.25, f0=0.2, cone="polygon", margin=0.4)
    state, ref = Motion(rng), Motion(rng)
    states, refs = Motion(rng), Motion(rng)
    for name in ("position", "velocity", "acceleration", "axis", "omega", "alpha"):
        setattr(states, name, rng.normal(size=(n, 3)))
        setattr(refs, name, rng.normal(size=(n, 3)))
    gains = {"kp": 400.0, "kv": 40.0, "kp_rot": 300.0, "kv_rot": 30.0}
    masses, inertia = rng.uniform(0.01, 0.03, n), np.stack([spd(rng, 3, 1e-3) for _ in range(n)])
    J_pinv = law.damped_pinv_blocks(J, 1e-6)
    batch = {
        "object_acceleration": law.object_acceleration(states, refs, **gains),
        "object_wrench": law.object_wrench(masses, inertia, states.omega, a_d, -v[:, :3]),
        "internal_part": law.internal_part(c, W, W_pinv),
        "internal_force_step": law.internal_force_step(step, W_pinv, dW, 50.0, 0.01),
        "cones": law.largest_steps_inside_cones(c, step, active, sliding, settings_),
        "J_pinv": J_pinv,
        "finger_inertia": law.finger_inertia_torques(M, J_pinv, W, dW, dJ, qvel, a_d, v, touching),
        "feedforward": law.damping_feedforward_torques(qvel, J_pinv, W, v, touching),
        "approach": approach_torques(qvel, qvel, J_pinv, W, v, ~touching, 0.01, 0.005),
        "joint_torques": law.joint_torques(J, c, qvel, a_d[:, :1], v[:, :1]),
    }
    for i in range(n):
        state.position, state.velocity, state.axis, state.omega = (
            getattr(states, f)[i] for f in ("position", "velocity", "axis", "omega")
        )
        for f in ("position", "velocity", "acceleration", "axis", "omega", "alpha"):
            setattr(ref, f, getattr(refs, f)[i])
        alone = {
            "object_acceleration": law.object_acceleration(state, ref, **gains),
            "object_wrench": law.object_wrench(
                masses[i], inertia[i], states.omega[i], a_d[i], -v[i, :3]
            ),
            "internal_part": law.internal_part(c[i], W[i], W_pinv[i]),
            "internal_force_step": law.internal_force_step(step[i], W_pinv[i], dW[i], 50.0, 0.01),
            "cones": law.largest_step_inside_cones(
                c[i], step[i], active[i], set(np.flatnonzero(sliding[i])), settings_
            ),
            "J_pinv": law.damped_pinv_blocks(J[i], 1e-6),
            "finger_inertia": law.finger_inertia_torques(
                M[i], J_pinv[i], W[i], dW[i], dJ[i], qvel[i], a_d[i], v[i], touching[i]
            ),
            "feedforward": law.damping_feedforward_torques(
                qvel[i], J_pinv[i], W[i], v[i], touching[i]
            ),
            "approach": approach_torques(
                qvel[i], qvel[i], J_pinv[i], W[i], v[i], ~touching[i], 0.01, 0.005
            ),
            "joint_torques": law.joint_torques(J[i], c[i], qvel[i], a_d[i, :1], v[i, :1]),
        }
        for name, value in alone.items():
            np.testing.assert_array_equal(batch[name][i], value, err_msg=f"{name}, env {i}")


def test_the_controllers_right_inverse_of_a_batch_falls_back_per_env() -> None:
    """A batch where one env lost fingers (W W^T singular): that env gets np.linalg.pinv,
    the others ``W^T (W W^T)^-1``."""
    rng = np.random.default_rng(4)
    W = np.stack([cylinder_grasp(rng) for _ in range(3)])
    W[1, :, 3:] = 0.0  # env 1: one finger left
    result = right_inverses(W)
    np.testing.assert_allclose(result[1], np.linalg.pinv(W[1]), atol=1e-12)
    for i in (0, 2):
        np.testing.assert_allclose(result[i], pseudo_inverse(W[i]), rtol=1e-9, atol=1e-9)


# ---------------------------------------------------------------- helpers and layering
def test_right_inverse_falls_back_to_least_squares_only_when_asked() -> None:
    """The controller's W+ (a finger may be missing: zero columns) is np.linalg.pinv where
    W W^T is singular; the grip transform's own W+ still refuses rank < 6."""
    rng = np.random.default_rng(2)
    W = cylinder_grasp(rng)
    np.testing.assert_allclose(pseudo_inverse(W, least_squares_if_singular=True), pseudo_inverse(W))
    lost = W.copy()
    lost[:, 3:] = 0.0  # one finger left: rank 3
    np.testing.assert_allclose(
        pseudo_inverse(lost, least_squares_if_singular=True), np.linalg.pinv(lost), atol=1e-12
    )
    with pytest.raises(GraspRankError, match="rank W = 3"):
        pseudo_inverse(lost)


@settings(max_examples=30, deadline=None)
@given(seed=SEEDS)
def test_cross3_is_the_cross_product(seed: int) -> None:
    a, b = np.random.default_rng(seed).normal(size=(2, 3))
    np.testing.assert_allclose(cross3(a, b), np.cross(a, b), rtol=1e-12, atol=1e-15)


def test_the_law_imports_only_numpy_and_the_grasp_layer() -> None:
    """law.py sits below glove/sim/envs: it may not import them (nor mujoco)."""
    source = Path(law.__file__).read_text(encoding="utf-8")
    imported = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            imported |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            imported.add(node.module)
    allowed = ("numpy", "ias_gym.grasp", "ias_gym.errors", "typing", "collections", "__future__")
    assert imported and all(m.split(".")[0] in allowed or m.startswith(allowed) for m in imported)
    assert not any(m.startswith(("ias_gym.sim", "ias_gym.envs", "mujoco")) for m in imported)


def test_the_adapter_weighs_the_pen_with_the_model_gravity() -> None:
    """GripTransformController passes the model's gravity (MuJoCo's -z is the paper's -y) to
    eq. (33): on a model with weaker gravity the contacts carry less weight."""
    env = gym.make("IAS-PenSlide-v0")
    env.reset(seed=0)
    u = env.unwrapped
    assert isinstance(u, PenHandEnv)
    mass = u.physics.pen_mass_nominal
    wrench = GripTransformController().object_wrench(u, np.zeros(6))
    assert wrench[1] == pytest.approx(mass * 9.81, rel=1e-12)
    u.model.opt.gravity[:] = [0.0, 0.0, -4.0]
    wrench = GripTransformController().object_wrench(u, np.zeros(6))
    np.testing.assert_allclose(wrench[:3], [0.0, mass * 4.0, 0.0], rtol=1e-12, atol=1e-15)
    env.close()


# ---------------------------------------------------------------- offsets at sliding contacts
@settings(max_examples=60, deadline=None)
@given(seed=SEEDS)
def test_offset_keeps_kinetic_friction_and_stays_internal(seed: int) -> None:
    """An internal-force offset keeps every sliding contact on its kinetic-friction line
    ``c_t = mu c_n s``, stays in the null space of W (no net wrench), is the requested offset
    when nothing slides, and changes the request as little as possible (a projection)."""
    rng = np.random.default_rng(seed)
    W = cylinder_grasp(rng)
    N = null_space_basis(W)
    f = rng.normal(scale=0.1, size=N.shape[1])
    mu = 0.25
    np.testing.assert_allclose(law.keep_sliding_friction(N, f, {}, mu), N @ f, atol=1e-15)
    angle = rng.uniform(0, 2 * np.pi)
    sliding = {int(rng.integers(K)): np.array([np.cos(angle), np.sin(angle)])}
    offset = law.keep_sliding_friction(N, f, sliding, mu)
    np.testing.assert_allclose(W @ offset, 0.0, atol=1e-12)
    for k, s in sliding.items():
        c = offset[3 * k : 3 * k + 3]
        np.testing.assert_allclose(c[1:], mu * c[0] * s, atol=1e-12)
    # A projection: applying it again changes nothing, and what it removed is orthogonal.
    kept = N.T @ offset
    np.testing.assert_allclose(law.keep_sliding_friction(N, kept, sliding, mu), offset, atol=1e-12)
    assert abs((f - kept) @ kept) < 1e-12


def test_a_fingers_force_resolution_is_its_first_joint_to_slip() -> None:
    """The least normal force that turns one of a finger's joints past its dry friction:
    min_j F_j / |n . J_j| over the joints the force loads; none without joint friction."""
    from ias_gym.baselines.grip_transform_terms import force_resolution

    J = np.zeros((6, 5))
    J[0:3, 0:3] = [[0.02, 0.0, 0.01], [0.0, 0.05, 0.0], [0.0, 0.0, 0.04]]  # finger 0, dofs 0-2
    J[3:6, 3:5] = [[0.03, 0.0], [0.0, 0.0], [0.0, 0.06]]  # finger 1, dofs 3-4
    frames = np.tile(np.eye(3), (2, 1, 1))
    frames[0, 0] = [0.0, 1.0, 0.0]  # finger 0 pressed along y: only dof 1 is loaded
    frames[1, 0] = [0.6, 0.0, 0.8]  # finger 1: dof 3 (0.018) and dof 4 (0.048)
    coulomb = np.array([0.02, 0.02, 0.02, 0.01, 0.03])
    res = force_resolution(J, frames, coulomb)
    np.testing.assert_allclose(res, [0.02 / 0.05, min(0.01 / 0.018, 0.03 / 0.048)])
    np.testing.assert_array_equal(force_resolution(J, frames, np.zeros(5)), [0.0, 0.0])


def test_the_resolvable_squeeze_only_raises_a_squeeze_too_light_to_set() -> None:
    from ias_gym.baselines.grip_transform_terms import force_resolution, resolvable_squeeze

    J = np.zeros((6, 2))
    J[0, 0], J[3, 1] = 0.05, 0.05  # each finger's normal loads one joint with 0.05 N m/N
    frames = np.tile(np.eye(3), (2, 1, 1))
    coulomb = np.array([0.02, 0.02])  # force resolution 0.4 N each
    active = np.array([True, True])
    c_p = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0])  # finger 0 carries the load
    c_h = np.array([0.05, 0.01, 0.0, 0.05, -0.01, 0.0])  # finger 1 barely pressed
    out = resolvable_squeeze(c_p, c_h, 0.5, J, frames, coulomb, active)
    normals = (c_p + out)[0::3]
    floor = 0.5 * force_resolution(J, frames, coulomb)
    assert np.all(normals >= floor - 1e-12) and normals[1] == pytest.approx(floor[1])
    np.testing.assert_allclose(out, (out[0] / c_h[0]) * c_h)  # a scale of c_h: still internal
    # off, without friction, or already firm: unchanged (the same array)
    assert resolvable_squeeze(c_p, c_h, 0.0, J, frames, coulomb, active) is c_h
    assert resolvable_squeeze(c_p, c_h, 0.5, J, frames, np.zeros(2), active) is c_h
    firm = 10 * c_h
    assert resolvable_squeeze(c_p, firm, 0.5, J, frames, coulomb, active) is firm
    # a finger out of contact asks for nothing
    lifted = np.array([True, False])
    assert resolvable_squeeze(c_p, c_h, 0.5, J, frames, coulomb, lifted) is c_h

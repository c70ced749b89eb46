"""The Shadow hand as a pen hand: loaded from Gymnasium-Robotics' installed model, its coupled
distal joints honoured in the grasp model's coordinates, the Theorem-1 expert on it unchanged.

The spec-driven checks every hand shares (keyframe, shapes, contact ranges) are in
tests/test_hand3f.py, parametrised over the registry; what the external hands share in
tests/test_external_hands.py."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.baselines.expert import ExpertPolicy
from ias_gym.rollout import FunctionPolicy, rollout
from ias_gym.sim.external_hands import SHADOW_COUPLING, shadow_package_dir
from ias_gym.sim.grasp_pose import place_grasp
from ias_gym.sim.pen_hand import PenHandPhysics
from tests.closed_loop import perturbed_starts


@pytest.fixture
def shadow() -> PenHandPhysics:
    return PenHandPhysics.from_assets(hand="shadow")


def _press(p: PenHandPhysics, seconds: float = 0.03, seed: int = 0) -> None:
    """Squeeze the pen with torques along -J^T n (the tips push into it) plus noise, so that
    contacts, the coupling and every joint carry force (30 ms: the pen is not held yet)."""
    rng = np.random.default_rng(seed)
    for _ in range(round(seconds / p.model.opt.timestep)):
        contacts = p.fingertip_contacts()
        jac = p.fingertip_jacobians(contacts)
        push = np.zeros(3 * p.n_fingers)
        push[0::3] = 0.8  # N along each contact normal
        tau = jac.T @ push + p.hand_bias_forces() + rng.normal(0.0, 0.01, p.n_hand_dofs)
        p.set_hand_torques(tau)
        mujoco.mj_step(p.model, p.data)
    mujoco.mj_forward(p.model, p.data)


def test_the_model_comes_from_the_installed_package() -> None:
    """Nothing of the Shadow model is copied into this repository: its files are read from
    Gymnasium-Robotics' package folder."""
    root = shadow_package_dir()
    assert (root / "hand" / "robot.xml").is_file()
    assets = Path(importlib.util.find_spec("ias_gym.assets").origin).parent  # type: ignore[arg-type, union-attr]
    assert not list(assets.glob("**/*.stl"))
    assert not (assets / "robot.xml").exists()


def test_driven_joints_have_the_models_force_ranges(shadow: PenHandPhysics) -> None:
    """Every motor's range is the force range of the model's own actuator of that joint (the
    first finger's J3/J2 0.9 N m, its J1 0.7245 N m; the thumb's J4 2.3722 N m)."""
    m = shadow.model
    ranges = m.actuator_ctrlrange[shadow.hand_actuator_ids, 1]
    np.testing.assert_allclose(ranges[:3], [0.9, 0.9, 0.7245])
    assert ranges[3] == pytest.approx(2.3722)
    assert m.nu == shadow.n_hand_dofs == 9


def test_the_distal_joint_follows_the_middle_one(shadow: PenHandPhysics) -> None:
    """The model's J0 is not driven: it keeps ``SHADOW_COUPLING`` times J1 while the fingers
    press the pen, within 0.01 rad (the equality is soft; the model's own coupling tendon
    leaves J0 0.001 m / 0.00705 m = 0.14 rad of slack)."""
    assert [ratio for _, _, ratio in shadow.coupled] == [SHADOW_COUPLING] * 2
    _press(shadow)
    m, d = shadow.model, shadow.data
    for finger in ("f1", "f3"):
        dip = d.qpos[m.joint(f"{finger}_dip").qposadr[0]]
        pip = d.qpos[m.joint(f"{finger}_pip").qposadr[0]]
        assert dip == pytest.approx(SHADOW_COUPLING * pip, abs=0.01)
    assert shadow.fingertip_contacts().active.all()


def _constraint_forces(p: PenHandPhysics, kinds: set[int]) -> np.ndarray:
    """MuJoCo's constraint forces on every dof from the constraint rows of ``kinds``."""
    m, d = p.model, p.data
    jac = np.zeros((d.nefc, m.nv))
    if mujoco.mj_isSparse(m):
        mujoco.mju_sparse2dense(jac, d.efc_J, d.efc_J_rownnz, d.efc_J_rowadr, d.efc_J_colind)
    else:
        jac[:] = d.efc_J.reshape(d.nefc, m.nv)
    rows = np.isin(d.efc_type, list(kinds))
    out: np.ndarray = jac[rows].T @ d.efc_force[rows]
    return out


def test_eq35_holds_in_the_driven_coordinates(shadow: PenHandPhysics) -> None:
    """With S the map from driven to all joint velocities: the coupling's own force drops out
    (S^T of it is zero), -J^T c is S^T of the contacts' forces, and
    M theta_dd + H = tau - J^T c up to the model's joint friction (frictionloss 1 mN m)."""
    _press(shadow)
    c = shadow.contact_intensities()
    jac = shadow.fingertip_jacobians()
    cnstr = mujoco.mjtConstraint
    coupling = _constraint_forces(shadow, {cnstr.mjCNSTR_EQUALITY})
    assert np.abs(coupling).max() > 1e-3  # the coupling does carry force ...
    np.testing.assert_allclose(shadow.hand_forces(coupling), 0.0, atol=1e-9)  # ... S^T removes
    contact = {cnstr.mjCNSTR_CONTACT_FRICTIONLESS, cnstr.mjCNSTR_CONTACT_PYRAMIDAL}
    contact |= {cnstr.mjCNSTR_CONTACT_ELLIPTIC}
    np.testing.assert_allclose(
        -jac.T @ c, shadow.hand_forces(_constraint_forces(shadow, contact)), atol=1e-9
    )
    m, h = shadow.hand_mass_matrix(), shadow.hand_bias_forces()
    np.testing.assert_allclose(m, m.T, atol=1e-15)
    assert np.linalg.eigvalsh(m).min() > 0
    friction = shadow.hand_forces(_constraint_forces(shadow, {cnstr.mjCNSTR_FRICTION_DOF}))
    assert np.abs(friction).max() <= 0.001 * (1 + SHADOW_COUPLING) + 1e-9
    # with MuJoCo's accelerations of every joint: S^T M qdd_all + H = tau - J^T c + ..., to
    # the constraint solver's convergence (it stops at opt.tolerance, 1e-8: measured up to
    # 1.4e-6 N m of a 0.12 N m load, 2e-10 at a tolerance of 1e-12), far below any term of
    # the equation (the joints' friction alone is up to 1 mN m)
    inertial = np.zeros(shadow.model.nv)
    mujoco.mj_mulM(shadow.model, shadow.data, inertial, shadow.data.qacc)
    load = shadow.hand_torques() - jac.T @ c + friction
    scale = np.abs(load).max()
    np.testing.assert_allclose(shadow.hand_forces(inertial) + h, load, atol=1e-4 * scale)
    # the law's model, M of the driven joints' accelerations alone, is off by the soft
    # equality's give only (the distal joint's acceleration is not exactly ratio times its
    # leader's): a few percent of the torques
    qacc = shadow.data.qacc[shadow.hand_dof_ids]
    assert np.abs(m @ qacc + h - load).max() < 0.05 * np.abs(load).max()


def test_place_grasp_moves_the_coupled_joints_too(shadow: PenHandPhysics) -> None:
    """The grasp's inverse kinematics solves in the driven joints and sets each distal joint
    from its middle one: the tips land on a tilted pen."""
    err = place_grasp(shadow, [0.001, 0.0, 0.0], [0.0, 0.0, 0.15], [-0.034, 0.001, 0.041])
    assert err < 1e-6
    m, d = shadow.model, shadow.data
    for finger in ("f1", "f3"):
        dip = d.qpos[m.joint(f"{finger}_dip").qposadr[0]]
        pip = d.qpos[m.joint(f"{finger}_pip").qposadr[0]]
        assert dip == pytest.approx(SHADOW_COUPLING * pip, abs=1e-12)
    assert shadow.fingertip_contacts().active.all()


@pytest.mark.closed_loop
@pytest.mark.parametrize("seed", [31, 32])
def test_expert_rotates_the_pen_on_shadow_from_nearby_starts(seed: int) -> None:
    """The expert (no hand-specific code) succeeds on the Shadow hand from every start: the
    pen centre stays within 2 mm and every internal-force problem has a solution."""
    env = gym.make("IAS-PenRotate-Shadow-v0")
    policy = ExpertPolicy(env)
    for start, options in enumerate(perturbed_starts(env, seed)):
        info = rollout(env, policy, seed, reset_options=options, keep_infos=False).final_info
        assert info["is_success"], (start, info)
        assert info["max_position_error"] < 0.002, start
        assert policy.controller.infeasible_count == 0, start


def test_the_pen_falls_without_the_law() -> None:
    """The success test can fail: zero torques (the fingers' weight unbalanced) drop the pen."""
    env = gym.make("IAS-PenRotate-Shadow-v0")
    zero = np.zeros(env.action_space.shape)
    trajectory = rollout(env, FunctionPolicy(lambda obs: zero), 0, keep_infos=False)
    assert trajectory.final_info["dropped"] and not trajectory.is_success

"""PenHandPhysics: frames, W and c against the paper, J against MuJoCo's constraint forces."""

from __future__ import annotations

import importlib.resources

import mujoco
import numpy as np
import pytest
from paper_reference import eq16

from ias_gym.sim import (
    FINGERS,
    R_PAPER_TO_MJ,
    NameNotFoundError,
    PenHandPhysics,
    load_pen_hand_model,
    matrix_to_rpy,
    mj_to_paper,
    paper_to_mj,
    rpy_to_matrix,
    wrench_mj_to_paper,
    wrench_paper_to_mj,
)

R_PEN = 0.01  # [m]
PHI = (0.03, 0.02, 0.02, 0.03)  # [m]


def notes_w(phi: tuple[float, ...] = PHI, r: float = R_PEN) -> np.ndarray:
    """Eq. (16) as corrected in docs/NOTES.md (written out independently of the package)."""
    return eq16(phi, r)


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return load_pen_hand_model()


def _pen_first_model() -> mujoco.MjModel:
    """The scene with ellipsoid (= spherical) tips: MuJoCo then lists the pen as geom1."""
    with importlib.resources.as_file(
        importlib.resources.files("ias_gym.assets") / "scene_pen.xml"
    ) as path:
        spec = mujoco.MjSpec.from_file(str(path))
    for f in FINGERS:
        geom = spec.geom(f"{f}_tip_collision")
        geom.type = mujoco.mjtGeom.mjGEOM_ELLIPSOID
        geom.size = [0.005, 0.005, 0.005]
    return spec.compile()


@pytest.fixture(scope="module")
def pen_first_model() -> mujoco.MjModel:
    return _pen_first_model()


@pytest.fixture(params=["tip_is_geom1", "pen_is_geom1"])
def physics(
    request: pytest.FixtureRequest, model: mujoco.MjModel, pen_first_model: mujoco.MjModel
) -> PenHandPhysics:
    """Both orders of the pen/tip geoms in data.contact (DESIGN pitfall: signs per contact)."""
    m = model if request.param == "tip_is_geom1" else pen_first_model
    p = PenHandPhysics(m, mujoco.MjData(m))
    p.reset("grasp")
    pen_first = p.data.contact.geom[: p.data.ncon, 0] == m.geom("pen").id
    assert p.data.ncon == 4 and pen_first.all() == (request.param == "pen_is_geom1")
    return p


def squeeze(p: PenHandPhysics, steps: int = 10, normal: float = 0.3) -> None:
    """Fingers push inward with a constant torque J^T c_d (c_d = `normal` N along each normal)."""
    tau = p.fingertip_jacobians().T @ np.tile([normal, 0.0, 0.0], 4)
    p.set_hand_torques(tau)
    for _ in range(steps):
        mujoco.mj_step(p.model, p.data)
    mujoco.mj_forward(p.model, p.data)


# --- frames -----------------------------------------------------------------------------


def test_paper_to_mujoco_mapping() -> None:
    np.testing.assert_allclose(R_PAPER_TO_MJ @ R_PAPER_TO_MJ.T, np.eye(3))
    assert np.linalg.det(R_PAPER_TO_MJ) == pytest.approx(1.0)
    np.testing.assert_allclose(paper_to_mj([1, 0, 0]), [1, 0, 0])  # pen axis
    np.testing.assert_allclose(paper_to_mj([0, 1, 0]), [0, 0, 1])  # up
    np.testing.assert_allclose(paper_to_mj([0, 0, 1]), [0, -1, 0])  # lateral
    v = np.random.default_rng(0).normal(size=(5, 3))
    np.testing.assert_allclose(mj_to_paper(paper_to_mj(v)), v)
    w = np.random.default_rng(1).normal(size=(4, 6))
    np.testing.assert_allclose(wrench_paper_to_mj(wrench_mj_to_paper(w)), w)
    np.testing.assert_allclose(wrench_paper_to_mj([0, 1, 0, 0, 0, 1]), [0, 0, 1, 0, -1, 0])


def test_rpy_round_trip_and_convention() -> None:
    rpy = np.array([0.3, -0.2, 0.1])
    np.testing.assert_allclose(matrix_to_rpy(rpy_to_matrix(rpy)), rpy)
    # yaw alone rotates the pen axis (x) towards up (y): the see-saw of sec. 4.3
    np.testing.assert_allclose(
        rpy_to_matrix([0, 0, 0.2])[:, 0], [np.cos(0.2), np.sin(0.2), 0], atol=1e-15
    )


# --- contacts, W, c at the grasp keyframe --------------------------------------------------


def test_four_tip_contacts_with_paper_frames(physics: PenHandPhysics) -> None:
    c = physics.fingertip_contacts()
    assert c.active.all()
    assert ((c.depth > 0.2e-3) & (c.depth < 0.5e-3)).all()
    np.testing.assert_allclose(
        c.frames[:, 0], [[0, -1, 0], [0, 1, 0], [0, 1, 0], [0, -1, 0]], atol=1e-9
    )
    np.testing.assert_allclose(c.frames[:, 1], np.tile([1.0, 0, 0], (4, 1)), atol=1e-9)
    np.testing.assert_allclose(c.frames[:, 2], np.tile([0, 0, 1.0], (4, 1)), atol=1e-9)
    np.testing.assert_allclose(c.points[:, 0], [-0.03, -0.02, 0.02, 0.03], atol=1e-6)
    assert physics.n_link_contacts() == 0


def test_wrench_matrix_matches_eq_16(physics: PenHandPhysics) -> None:
    w, active = physics.wrench_matrix()
    assert w.shape == (6, 12) and active.all()
    expected = notes_w()
    np.testing.assert_allclose(w[:3], expected[:3], atol=1e-9)
    # soft contacts: the point sits half the penetration inside the pen (~0.15 mm)
    np.testing.assert_allclose(w[3:], expected[3:], atol=1e-3)
    assert np.linalg.matrix_rank(w) == 6


def test_moments_are_about_the_pens_centre(physics: PenHandPhysics) -> None:
    """Slide the pen 1 mm along +x under the tips: every phi_i changes by 1 mm."""
    physics.data.qpos[physics.pen_qpos_adr] += 1e-3
    mujoco.mj_forward(physics.model, physics.data)
    w, active = physics.wrench_matrix()
    assert active.all()
    expected = notes_w(phi=(0.031, 0.021, 0.019, 0.029))
    np.testing.assert_allclose(w, expected, atol=2e-4)  # r is 0.15 mm short (soft contact)


def test_missing_finger_gives_zero_columns(physics: PenHandPhysics) -> None:
    q = physics.model.jnt_qposadr[physics.model.joint("f1_abd").id]
    physics.data.qpos[q] = 0.3  # swing finger 1 sideways, off the pen
    mujoco.mj_forward(physics.model, physics.data)
    cts = physics.fingertip_contacts()
    w, active = physics.wrench_matrix(cts)
    assert active.tolist() == [False, True, True, True] and not cts.active[0]
    assert not w[:, :3].any() and not physics.contact_intensities(cts)[:3].any()
    frame = cts.frames[0]
    np.testing.assert_allclose(frame @ frame.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(cts.points[0], physics.tip_positions()[0])


def test_intensities_balance_the_pen(physics: PenHandPhysics) -> None:
    """W c + gravity = the pen's rate of momentum (Newton-Euler, eq. 33) - signs of W and c."""
    squeeze(physics)
    cts = physics.fingertip_contacts()
    assert cts.active.all() and physics.n_link_contacts() == 0
    c = physics.contact_intensities(cts)
    w, _ = physics.wrench_matrix(cts)
    assert (c[0::3] > 0.05).all()  # all four fingers push
    d, m = physics.data, physics.pen_mass()
    qacc = d.qacc[physics.pen_dof_adr : physics.pen_dof_adr + 6]
    rot = d.xmat[physics.pen_body_id].reshape(3, 3)
    accel = mj_to_paper(qacc[:3])
    alpha = mj_to_paper(rot @ qacc[3:])  # at rest omega = 0, no gyroscopic term worth keeping
    gravity = np.array([0.0, -m * 9.81, 0.0, 0.0, 0.0, 0.0])
    rate = np.concatenate([m * accel, physics.pen_inertia() @ alpha])
    np.testing.assert_allclose(w @ c + gravity, rate, atol=2e-4)


def test_jacobian_transpose_reproduces_constraint_forces(physics: PenHandPhysics) -> None:
    """-J^T c is the contacts' load on the hand: MuJoCo's qfrc_constraint (eq. 35)."""
    squeeze(physics)
    cts = physics.fingertip_contacts()
    c = physics.contact_intensities(cts)
    jac = physics.fingertip_jacobians(cts)
    qfrc = physics.data.qfrc_constraint[physics.hand_dof_ids]
    assert np.abs(qfrc).max() > 1e-3  # the contacts do carry force
    np.testing.assert_allclose(-jac.T @ c, qfrc, atol=1e-12)
    # and the whole of eq. (35): M theta_dd + H = tau - J^T c
    m, h = physics.hand_mass_matrix(), physics.hand_bias_forces()
    qacc = physics.data.qacc[physics.hand_dof_ids]
    np.testing.assert_allclose(m @ qacc + h, physics.hand_torques() - jac.T @ c, atol=1e-12)


def test_mass_matrix_and_bias_forces(physics: PenHandPhysics) -> None:
    m = physics.hand_mass_matrix()
    assert m.shape == (12, 12)
    np.testing.assert_allclose(m, m.T)
    assert np.linalg.eigvalsh(m).min() > 0
    off_block = m.copy()
    for i in range(4):
        off_block[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = 0
    assert not off_block.any()
    # at rest gravity is compensated: H = 0 although qfrc_bias holds gravity
    assert np.abs(physics.data.qfrc_bias[physics.hand_dof_ids]).max() > 1e-3
    np.testing.assert_allclose(physics.hand_bias_forces(), 0.0, atol=1e-12)


# --- pen pose and twist -----------------------------------------------------------------


def test_pen_pose_and_twist_in_paper_frame(physics: PenHandPhysics) -> None:
    d, qa, va = physics.data, physics.pen_qpos_adr, physics.pen_dof_adr
    rpy = np.array([0.4, -0.15, 0.25])  # roll, pitch, yaw about paper x, y, z
    rot_mj = R_PAPER_TO_MJ @ rpy_to_matrix(rpy) @ R_PAPER_TO_MJ.T
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, rot_mj.reshape(-1))
    offset = np.array([0.001, -0.002, 0.003])  # paper frame [m]
    d.qpos[qa : qa + 3] = physics.origin_mj + paper_to_mj(offset)
    d.qpos[qa + 3 : qa + 7] = quat
    v, omega = np.array([0.01, 0.02, -0.03]), np.array([0.5, -1.0, 2.0])  # paper frame
    d.qvel[va : va + 3] = paper_to_mj(v)
    d.qvel[va + 3 : va + 6] = rot_mj.T @ paper_to_mj(omega)  # MuJoCo: body frame
    pos, angles = physics.pen_pose()
    np.testing.assert_allclose(pos, offset, atol=1e-12)
    np.testing.assert_allclose(angles, rpy, atol=1e-12)
    lin, ang = physics.pen_twist()
    np.testing.assert_allclose(lin, v, atol=1e-12)
    np.testing.assert_allclose(ang, omega, atol=1e-12)
    np.testing.assert_allclose(physics.pen_axis(), rpy_to_matrix(rpy)[:, 0], atol=1e-12)


def test_see_saw_is_yaw(physics: PenHandPhysics) -> None:
    """A tilt raising the pen's +x end (MuJoCo z up) is +yaw about paper z."""
    qa = physics.pen_qpos_adr
    quat = np.zeros(4)
    mujoco.mju_axisAngle2Quat(quat, np.array([0.0, -1.0, 0.0]), 0.3)  # paper z = -MuJoCo y
    physics.data.qpos[qa + 3 : qa + 7] = quat
    mujoco.mj_forward(physics.model, physics.data)
    np.testing.assert_allclose(physics.pen_pose()[1], [0, 0, 0.3], atol=1e-12)
    tip_end = (
        physics.data.xpos[physics.pen_body_id]
        + physics.data.xmat[physics.pen_body_id].reshape(3, 3)[:, 0]
    )
    assert tip_end[2] > physics.origin_mj[2]


def test_pen_mass_and_inertia(physics: PenHandPhysics) -> None:
    assert physics.pen_mass() * 9.81 == pytest.approx(1.0)
    inertia = physics.pen_inertia()
    np.testing.assert_allclose(inertia, np.diag(np.diag(inertia)), atol=1e-15)
    roll, pitch, yaw = np.diag(inertia)
    assert pitch == pytest.approx(yaw) and 15 < pitch / roll < 30  # DESIGN: ~20x


# --- names --------------------------------------------------------------------------------


def test_unknown_names_list_what_exists(model: mujoco.MjModel) -> None:
    d = mujoco.MjData(model)
    with pytest.raises(NameNotFoundError, match=r"f9_abd.*Available joint names: \[.*'f1_abd'"):
        PenHandPhysics(model, d, fingers=("f1", "f9"))
    with pytest.raises(NameNotFoundError, match=r"pencil.*Available body names: \[.*'pen'"):
        PenHandPhysics(model, d, pen="pencil")
    with pytest.raises(NameNotFoundError, match="grasp"):
        PenHandPhysics(model, d).reset("no_such_key")

"""The MJCF assets: every scene compiles and steps cleanly; the pen hand is built as specified."""

from __future__ import annotations

import importlib.resources

import mujoco
import numpy as np
import pytest

from ias_gym.sim.pen_hand import FINGER_JOINTS, FINGERS, load_pen_hand_model

ASSETS = importlib.resources.files("ias_gym.assets")
XML_FILES = sorted(p.name for p in ASSETS.iterdir() if p.name.endswith(".xml"))
SCENES = [name for name in XML_FILES if name.startswith("scene")]

PHI = np.array([0.03, 0.02, 0.02, 0.03])  # paper's contact distances l_i [m]
TOP = np.array([1.0, -1.0, -1.0, 1.0])  # finger above (+1) or below (-1) the pen
OUTWARD = np.array([-1.0, -1.0, 1.0, 1.0])  # direction along x away from the pen's centre
PEN_R, TIP_R = 0.01, 0.005  # [m]
CENTRE = np.array([0.0, 0.0, 0.2])  # nominal pen centre, MuJoCo world [m]


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return load_pen_hand_model()


def test_scene_list_is_not_empty() -> None:
    assert "scene_pen.xml" in SCENES
    assert {"ias_hand.xml", "pen.xml"} <= set(XML_FILES)


@pytest.mark.parametrize("name", XML_FILES)
def test_every_xml_compiles(name: str) -> None:
    with importlib.resources.as_file(ASSETS / name) as path:
        mujoco.MjModel.from_xml_path(str(path))


@pytest.mark.parametrize("name", SCENES)
def test_scene_steps_one_second_under_random_control(name: str) -> None:
    m = load_pen_hand_model(name)
    d = mujoco.MjData(m)
    if m.nkey:
        mujoco.mj_resetDataKeyframe(m, d, 0)
    rng = np.random.default_rng(0)
    lo, hi = m.actuator_ctrlrange.T
    for _ in range(round(1.0 / m.opt.timestep)):
        d.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_step(m, d)
    warnings = {mujoco.mjtWarning(i).name: int(d.warning[i].number) for i in range(len(d.warning))}
    assert all(n == 0 for n in warnings.values()), warnings
    assert np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all() and np.isfinite(d.qacc).all()


def test_options_follow_the_design(model: mujoco.MjModel) -> None:
    assert model.opt.timestep == pytest.approx(0.001)
    assert int(model.opt.cone) == int(mujoco.mjtCone.mjCONE_ELLIPTIC)
    assert model.opt.impratio == pytest.approx(10.0)
    assert model.opt.iterations == 100
    for cam in ("front", "side"):
        model.camera(cam)


def test_names_and_actuators_are_systematic(model: mujoco.MjModel) -> None:
    for f in FINGERS:
        for j in FINGER_JOINTS:
            joint = model.joint(f"{f}_{j}")
            act = model.actuator(f"{f}_{j}")
            assert int(model.actuator_trnid[act.id, 0]) == joint.id
            assert int(model.jnt_type[joint.id]) == int(mujoco.mjtJoint.mjJNT_HINGE)
            assert bool(model.jnt_limited[joint.id])
            assert bool(model.actuator_ctrllimited[act.id])
            np.testing.assert_allclose(model.actuator_ctrlrange[act.id], [-0.5, 0.5])
            assert model.actuator_gear[act.id, 0] == 1.0
        site = model.site(f"{f}_tip")
        touch = model.sensor(f"{f}_touch")
        assert int(model.sensor_type[touch.id]) == int(mujoco.mjtSensor.mjSENS_TOUCH)
        assert int(model.sensor_objid[touch.id]) == site.id
    assert model.nu == 12


def test_hand_masses_and_gravity_compensation(model: mujoco.MjModel) -> None:
    for f in FINGERS:
        masses = [model.body(f"{f}_{b}").mass[0] for b in ("proximal", "distal", "fingertip")]
        np.testing.assert_allclose(masses, [0.015, 0.010, 0.005])
        for b in ("proximal", "distal", "fingertip"):
            assert model.body_gravcomp[model.body(f"{f}_{b}").id] == 1.0


def test_pen_is_the_papers_pen(model: mujoco.MjModel) -> None:
    geom = model.geom("pen")
    assert int(geom.type[0]) == int(mujoco.mjtGeom.mjGEOM_CAPSULE)
    np.testing.assert_allclose(geom.size[:2], [0.01, 0.05])  # radius, half-length of cylinder
    assert model.body("pen").mass[0] * 9.81 == pytest.approx(1.0, rel=1e-6)
    assert geom.friction[0] == pytest.approx(0.25)
    assert int(model.jnt_type[model.joint("pen").id]) == int(mujoco.mjtJoint.mjJNT_FREE)


def _can_collide(m: mujoco.MjModel, g1: int, g2: int) -> bool:
    return bool(
        (m.geom_contype[g1] & m.geom_conaffinity[g2])
        or (m.geom_contype[g2] & m.geom_conaffinity[g1])
    )


def test_fingers_collide_only_with_the_pen(model: mujoco.MjModel) -> None:
    hand_root = model.body("ias_hand").id
    hand = [g for g in range(model.ngeom) if model.body_rootid[model.geom_bodyid[g]] == hand_root]
    colliding = [g for g in hand if model.geom_contype[g] or model.geom_conaffinity[g]]
    assert colliding, "the hand has no collision geoms"
    pen, floor = model.geom("pen").id, model.geom("floor").id
    for g in colliding:
        assert _can_collide(model, g, pen)
        assert not _can_collide(model, g, floor)
        assert not any(_can_collide(model, g, h) for h in colliding)
    assert _can_collide(model, pen, floor)


def test_grasp_keyframe_has_four_shallow_tip_contacts(model: mujoco.MjModel) -> None:
    d = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, d, model.key("grasp").id)
    mujoco.mj_forward(model, d)
    tips = {model.geom(f"{f}_tip_collision").id: i for i, f in enumerate(FINGERS)}
    pen = model.geom("pen").id
    assert d.ncon == 4
    seen = {}
    for c in d.contact:
        pair = {int(c.geom[0]), int(c.geom[1])}
        assert pen in pair
        (tip,) = pair - {pen}
        seen[tips[tip]] = (c.pos.copy(), -c.dist)
    assert sorted(seen) == [0, 1, 2, 3]
    for i, (pos, depth) in seen.items():
        assert 0.2e-3 <= depth <= 0.5e-3
        expected = CENTRE + np.array([OUTWARD[i] * PHI[i], 0.0, TOP[i] * (PEN_R - depth / 2)])
        np.testing.assert_allclose(pos, expected, atol=1e-6)


# --- workspace: contact point, 1.5 cm further out along the pen, +-1 cm vertically ----------


def _ik(m: mujoco.MjModel, d: mujoco.MjData, finger: int, target: np.ndarray) -> float:
    """Damped least squares on one finger's tip site; returns the residual [m]."""
    f = FINGERS[finger]
    joints = [m.joint(f"{f}_{j}").id for j in FINGER_JOINTS]
    qadr, dadr = m.jnt_qposadr[joints], m.jnt_dofadr[joints]
    lo, hi = m.jnt_range[joints].T
    site = m.site(f"{f}_tip").id
    jac = np.zeros((3, m.nv))
    d.qpos[qadr] = [0.0, 0.4, 1.5]
    for _ in range(60):
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        err = target - d.site_xpos[site]
        mujoco.mj_jacSite(m, d, jac, None, site)
        j = jac[:, dadr]
        d.qpos[qadr] = np.clip(
            d.qpos[qadr] + j.T @ np.linalg.solve(j @ j.T + 1e-9 * np.eye(3), err), lo, hi
        )
    mujoco.mj_kinematics(m, d)
    return float(np.linalg.norm(target - d.site_xpos[site]))


@pytest.mark.parametrize("finger", range(4))
def test_workspace_reaches_contacts_outward_and_vertically(
    model: mujoco.MjModel, finger: int
) -> None:
    d = mujoco.MjData(model)
    pen_q = model.jnt_qposadr[model.joint("pen").id]
    pen = model.geom("pen").id
    f = FINGERS[finger]
    links = [model.geom(f"{f}_proximal_collision").id, model.geom(f"{f}_distal_collision").id]
    fromto = np.zeros(6)
    for slide in (0.0, 0.015):
        for dz in (-0.01, 0.0, 0.01):
            # The pen moved by dz, the tip touching it `slide` further out than the paper's l_i.
            d.qpos[pen_q : pen_q + 7] = [CENTRE[0], CENTRE[1], CENTRE[2] + dz, 1, 0, 0, 0]
            x = OUTWARD[finger] * (PHI[finger] + slide)
            target = CENTRE + np.array([x, 0.0, dz + TOP[finger] * (PEN_R + TIP_R)])
            assert _ik(model, d, finger, target) < 1e-6, (slide, dz)
            clearance = min(mujoco.mj_geomDistance(model, d, g, pen, 0.05, fromto) for g in links)
            assert clearance > 1e-3, (slide, dz, clearance)

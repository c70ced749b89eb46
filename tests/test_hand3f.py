"""The second robot hand ``ias3f``: its model, its grasp, the registry, the envs on it and the
Theorem-1 expert running on it unchanged (docs/DESIGN.md, "The second hand")."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.baselines.expert import ExpertPolicy
from ias_gym.errors import InputError
from ias_gym.grasp.internal_forces import (
    InfeasibleGraspError,
    InternalForceSettings,
    solve_internal_forces,
)
from ias_gym.grasp.pen_skill import grasp_wrench_matrix, gravity_wrench
from ias_gym.sim.grasp_pose import place_grasp
from ias_gym.sim.hands import HANDS, HandSpec, get_hand, hand_names
from ias_gym.sim.pen_hand import PenHandPhysics, rpy_to_matrix
from tests.closed_loop import perturbed_starts

MU = 0.25  # the pen's friction coefficient [-]
PENETRATION = 3e-4  # the keyframe's tip-pen overlap [m]


@pytest.fixture(params=hand_names())
def hand(request: pytest.FixtureRequest) -> tuple[HandSpec, PenHandPhysics]:
    """Each registered hand's spec and physics at its ``grasp`` keyframe."""
    return get_hand(request.param), PenHandPhysics.from_assets(hand=request.param)


# --- the model and its grasp ---------------------------------------------------------------
def test_registry_names_the_hands_and_ias3f_differs_from_ias4f() -> None:
    assert hand_names() == ["ias3f", "ias4f", "leap", "shadow"]
    three, four = get_hand("ias3f"), get_hand("ias4f")
    assert (three.n_fingers, three.n_dofs) == (3, 9)
    assert (four.n_fingers, four.n_dofs) == (4, 12)
    # Different links: the thumb's proximal link is longer than any of ias4f's.
    m3 = PenHandPhysics.from_assets(hand="ias3f").model
    m4 = PenHandPhysics.from_assets(hand="ias4f").model
    thumb = np.linalg.norm(m3.body("f2_distal").pos)
    assert thumb == pytest.approx(0.06) and thumb > np.linalg.norm(m4.body("f1_distal").pos)
    top = np.linalg.norm(m3.body("f1_distal").pos)
    assert top == pytest.approx(0.045)


def test_keyframe_tips_touch_the_pen_where_the_spec_says(
    hand: tuple[HandSpec, PenHandPhysics],
) -> None:
    """The ``grasp`` keyframe puts every tip 0.3 mm into the pen at the spec's contact_x, on
    the spec's side, with no finger link touching the pen."""
    spec, physics = hand
    contacts = physics.fingertip_contacts()
    assert contacts.active.all()
    np.testing.assert_allclose(contacts.depth, PENETRATION, atol=2e-5)
    tips = physics.tip_positions()
    np.testing.assert_allclose(tips[:, 0], spec.contact_x, atol=1e-6)
    np.testing.assert_array_equal(np.sign(tips[:, 1]), spec.sides)
    np.testing.assert_array_equal(physics.finger_sides, spec.sides)
    assert physics.n_link_contacts() == 0


def test_ias3f_grasp_is_force_closure() -> None:
    """Rank W = 6 and a strictly positive internal force inside the friction cones exists
    (the LP of eqs. 19-24 with no external wrench): with frictional point contacts that is
    force closure. Checked on the simulated contacts of the keyframe and on eq. (16)'s W of
    the spec's layout; the pen's weight is held too."""
    p = PenHandPhysics.from_assets(hand="ias3f")
    W_sim, active = p.wrench_matrix()
    spec = get_hand("ias3f")
    W_spec = grasp_wrench_matrix(spec.contact_x, spec.sides)
    assert active.all()
    for W in (W_sim, W_spec):
        assert W.shape == (6, 9) and np.linalg.matrix_rank(W, tol=1e-9) == 6
        for cone in ("box", "exact"):
            settings = InternalForceSettings(mu=MU, f0=0.1, cone=cone, margin=0.4)
            c = solve_internal_forces(W, np.zeros(6), None, settings).c.reshape(3, 3)
            np.testing.assert_allclose(W @ c.ravel(), 0.0, atol=1e-9)
            assert (c[:, 0] >= 0.1 - 1e-9).all()  # strictly compressive
            # strictly inside the cones (the margin leaves 40 % of mu unused)
            assert (np.linalg.norm(c[:, 1:], axis=1) <= 0.6 * MU * c[:, 0] + 1e-9).all()
            held = solve_internal_forces(W, gravity_wrench(1.0), None, settings).c
            np.testing.assert_allclose(W @ held, -gravity_wrench(1.0), atol=1e-9)


def test_three_fingers_on_one_side_are_not_force_closure() -> None:
    """The check above can fail: with all three fingers on top there is no squeeze."""
    W = grasp_wrench_matrix([-0.03, 0.0, 0.03], [1.0, 1.0, 1.0])
    with pytest.raises(InfeasibleGraspError):
        solve_internal_forces(W, np.zeros(6), None, InternalForceSettings(mu=MU, f0=0.1))


def test_physics_shapes_follow_the_hand(hand: tuple[HandSpec, PenHandPhysics]) -> None:
    spec, physics = hand
    k, n = spec.n_fingers, spec.n_dofs
    W, active = physics.wrench_matrix()
    assert W.shape == (6, 3 * k) and active.shape == (k,)
    assert physics.fingertip_jacobians().shape == (3 * k, n)
    assert physics.hand_mass_matrix().shape == (n, n)
    assert physics.hand_bias_forces().shape == (n,)
    assert physics.contact_intensities().shape == (3 * k,)
    assert physics.tip_positions().shape == (k, 3)
    assert physics.hand_qpos().shape == (n,) == physics.hand_actuator_ids.shape


def test_place_grasp_reaches_a_tilted_pen_on_ias3f() -> None:
    p = PenHandPhysics.from_assets(hand="ias3f")
    spec = get_hand("ias3f")
    rpy = np.array([0.0, 0.0, 0.25])
    x = np.array(spec.contact_x) + np.array([-0.004, 0.003, 0.002])
    err = place_grasp(p, [0.001, -0.001, 0.0], rpy, x)
    assert err < 1e-6
    tips = p.tip_positions() - [0.001, -0.001, 0.0]
    local = tips @ rpy_to_matrix(rpy)  # paper -> pen frame
    np.testing.assert_allclose(local[:, 0], x, atol=1e-6)
    radius = p.model.geom_size[p.tip_geom_ids, 0] + 0.01  # tip + pen [m]
    np.testing.assert_allclose(
        local[:, 1], np.array(spec.sides) * (radius - PENETRATION), atol=1e-6
    )


def _touches_at(p: PenHandPhysics, rpy: list[float], contact_x: np.ndarray) -> bool:
    """Whether IK from the ``grasp`` keyframe puts every tip on the pen at ``contact_x`` with
    no link touching it (from the keyframe: where an earlier query left the fingers must not
    decide, the IK is local)."""
    p.reset()
    err = place_grasp(p, np.zeros(3), rpy, contact_x, iterations=100, tolerance=1e-9)
    return err < 1e-6 and bool(p.fingertip_contacts().active.all()) and p.n_link_contacts() == 0


def test_contact_range_is_what_the_tips_reach(hand: tuple[HandSpec, PenHandPhysics]) -> None:
    """Each finger reaches both ends of its registered ``contact_range`` (the others at their
    nominal contacts), and not 3 mm beyond an end that lies on the pen's cylinder."""
    spec, p = hand
    ranges = zip(spec.contact_x, spec.contact_range, strict=True)
    assert spec.reach == pytest.approx(min(min(x - lo, hi - x) for x, (lo, hi) in ranges))
    for i, (lo, hi) in enumerate(spec.contact_range):
        for end, beyond in ((lo, lo - 0.003), (hi, hi + 0.003)):
            x = np.array(spec.contact_x)
            x[i] = end
            assert _touches_at(p, [0.0, 0.0, 0.0], x), (spec.name, i, end)
            if abs(beyond) < 0.05:  # an end inside the cylinder is the hand's own limit
                x[i] = beyond
                assert not _touches_at(p, [0.0, 0.0, 0.0], x), (spec.name, i, beyond)


def test_ias3f_links_clear_the_tilted_pen() -> None:
    """The design's point (assets/README.md): up to 0.35 rad of tilt both ways, no finger link
    comes within 1 mm of the pen (the first design's thumb link touched it at rest)."""
    p = PenHandPhysics.from_assets(hand="ias3f")
    m, d = p.model, p.data
    links = [g for g in range(m.ngeom) if p._hand_geom[g] and m.geom_contype[g]]
    assert len(links) == 6  # proximal and distal of three fingers
    for yaw in (-0.35, -0.2, 0.0, 0.2, 0.35):
        assert _touches_at(p, [0.0, 0.0, yaw], np.array(get_hand("ias3f").contact_x))
        clearance = min(mujoco.mj_geomDistance(m, d, g, p.pen_geom_id, 0.05, None) for g in links)
        assert clearance > 1e-3, (yaw, clearance)


@pytest.mark.parametrize("frequency", [2.0, 12.0])
def test_ias3f_links_stay_off_the_pen_under_load(frequency: float) -> None:
    """In closed loop at 0.35 rad no finger link touches the pen at any step. The static check
    above misses what broke the first design: the thumb's 1.4 N pressed its 5 mm tip 1.6 mm
    into the soft contact and its distal link onto the pen (394 of 400 steps)."""
    env = gym.make("IAS-PenRotate3F-v0", amplitude=0.35, frequency=frequency)
    policy = ExpertPolicy(env)
    obs, _ = env.reset(seed=0)
    touching = 0
    while True:
        obs, _, terminated, truncated, info = env.step(policy.predict(obs)[0])
        touching += env.unwrapped.physics.n_link_contacts() > 0
        if terminated or truncated:
            break
    assert info["is_success"] and touching == 0, touching


# --- the envs on the hand -----------------------------------------------------------------
def test_spaces_follow_the_hand() -> None:
    env = gym.make("IAS-PenRotate3F-v0")
    assert env.action_space.shape == (9,)
    assert env.observation_space.shape == (46,)  # 12 k + 19
    u = env.unwrapped
    np.testing.assert_allclose(u._ctrl_max, [0.35, 0.35, 0.35, 0.8, 0.8, 0.8, 0.35, 0.35, 0.35])
    obs, info = env.reset(seed=3)
    assert obs.shape == (46,) and info["fingers_in_contact"].all()
    assert info["max_contact_gap"].shape == (3,)
    assert gym.make("IAS-PenRotate-v0").action_space.shape == (12,)
    assert gym.make("IAS-PenRotate-v0").observation_space.shape == (55,)


def test_the_3f_id_is_the_task_with_hand_ias3f() -> None:
    a, b = gym.make("IAS-PenRotate3F-v0"), gym.make("IAS-PenRotate-v0", hand="ias3f")
    assert a.unwrapped.config == b.unwrapped.config
    obs_a, _ = a.reset(seed=4)
    obs_b, _ = b.reset(seed=4)
    np.testing.assert_array_equal(obs_a, obs_b)
    action = np.linspace(-0.2, 0.2, 9)
    np.testing.assert_array_equal(a.step(action)[0], b.step(action)[0])


@pytest.mark.parametrize("env_id", ["IAS-PenRotate-v0", "IAS-PenSlide-v0", "IAS-PenRotate3F-v0"])
def test_unknown_hand_is_an_input_error_naming_the_known_hands(env_id: str) -> None:
    with pytest.raises(InputError, match=r"'nope'.*ias3f, ias4f"):
        gym.make(env_id, hand="nope")


def test_pen_slide_refuses_the_three_finger_hand() -> None:
    with pytest.raises(InputError, match="four-finger sliding schedule"):
        gym.make("IAS-PenSlide-v0", hand="ias3f")


def test_why_there_is_no_three_finger_slide() -> None:
    """The thumb, ias3f's only finger below the pen, cannot slide along a still pen: its
    kinetic friction mu (m g + n1 + n3) exceeds the top fingers' mu (n1 + n3) for any squeeze
    (the LP has no solution); a bottom finger of ias4f can, the other one shares the weight."""
    settings = InternalForceSettings(mu=MU, f0=0.1)
    along = np.array([1.0, 0.0])  # sliding +x along the pen
    W3 = grasp_wrench_matrix([-0.03, 0.005, 0.03], [1.0, -1.0, 1.0])
    with pytest.raises(InfeasibleGraspError):
        solve_internal_forces(W3, gravity_wrench(1.0), {1: along}, settings)
    top = solve_internal_forces(W3, gravity_wrench(1.0), {2: along}, settings)  # a top one can
    assert top.c[6] > 0
    W4 = grasp_wrench_matrix([-0.03, -0.02, 0.025, 0.03], [1.0, -1.0, -1.0, 1.0])
    solve_internal_forces(W4, gravity_wrench(1.0), {2: along}, settings)


def test_amplitude_limit_is_the_hands_largest_tilt() -> None:
    for name, spec in HANDS.items():
        gym.make("IAS-PenRotate-v0", hand=name, amplitude=spec.max_tilt)
        with pytest.raises(ValueError, match="amplitude"):
            gym.make("IAS-PenRotate-v0", hand=name, amplitude=spec.max_tilt + 0.01)


def test_disturbances_are_sized_for_the_hand() -> None:
    env = gym.make(
        "IAS-PenRotate3F-v0", force_noise=0.01, joint_angle_noise=1e-4, internal_force_step=0.1
    )
    obs, _ = env.reset(seed=1)
    u = env.unwrapped
    assert u.disturbances.noise.force.shape == (3, 3)
    assert u.disturbances.n_internal == 3  # 3 k - 6
    obs, *_ = env.step(np.zeros(9))
    assert obs.shape == (46,)
    assert u.internal_force_reference().shape == (3,)


# --- the Theorem-1 expert, unchanged, on the second hand -----------------------------------
@pytest.mark.closed_loop
@pytest.mark.parametrize("seed", [11, 12])
def test_expert_rotates_the_pen_on_ias3f_from_nearby_starts(seed: int) -> None:
    """The expert (ias_gym.baselines.expert, no hand-specific code) succeeds on every start:
    the tilt tracks A sin(w t) within 1 % of A RMS, the pen centre stays within 2 mm."""
    env = gym.make("IAS-PenRotate3F-v0")
    policy = ExpertPolicy(env)
    for start, options in enumerate(perturbed_starts(env, seed)):
        obs, _ = env.reset(seed=seed, options=options)
        policy.reset()
        while True:
            action, _ = policy.predict(obs)
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        assert info["is_success"], (start, info)
        assert info["rms_tilt_error"] < 0.01 * env.unwrapped.config.amplitude, start
        assert info["max_position_error"] < 0.002, start
        assert policy.controller.infeasible_count == 0, start


@pytest.mark.closed_loop
@pytest.mark.parametrize("frequency", [2.0, 12.0])
def test_expert_reaches_the_registered_largest_tilt_on_ias3f(frequency: float) -> None:
    """``HandSpec.max_tilt`` is measured, not assumed: at A = max_tilt (0.4 rad) the expert
    still succeeds from every nearby start, at the slowest and the fastest frequency of the
    envelope (docs/DESIGN.md, "The second hand")."""
    amplitude = get_hand("ias3f").max_tilt
    env = gym.make("IAS-PenRotate3F-v0", amplitude=amplitude, frequency=frequency)
    policy = ExpertPolicy(env)
    for start, options in enumerate(perturbed_starts(env, 21, n=3)):
        obs, _ = env.reset(seed=21, options=options)
        policy.reset()
        while True:
            action, _ = policy.predict(obs)
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        assert info["is_success"], (start, info)
        assert info["rms_tilt_error"] < 0.02 * amplitude, start


def test_object_level_actions_follow_the_hand() -> None:
    """GripTransformAction on ias3f: 6 object accelerations + 3 k - 6 = 3 internal forces; a
    zero action is the expert's, bit for bit; an internal-force action changes the torques."""
    from ias_gym.baselines.action_wrapper import GripTransformAction

    def after_20_steps(seed: int = 2) -> GripTransformAction:
        wrapped = GripTransformAction(gym.make("IAS-PenRotate3F-v0"))
        wrapped.reset(seed=seed)
        for _ in range(20):
            wrapped.step(np.zeros(9))
        return wrapped

    wrapped = after_20_steps()
    assert wrapped.action_space.shape == (9,)
    env = gym.make("IAS-PenRotate3F-v0")
    expert = ExpertPolicy(env)
    obs, _ = env.reset(seed=2)
    for _ in range(20):
        obs, *_ = env.step(expert.predict(obs)[0])
    np.testing.assert_array_equal(wrapped.unwrapped.data.qpos, env.unwrapped.data.qpos)
    squeeze = np.zeros(9)
    squeeze[6] = 1.0  # along the first internal-force direction (the cones allow all of it)
    zero_tau = after_20_steps().action(np.zeros(9))
    assert np.abs(wrapped.action(squeeze) - zero_tau).max() > 1e-3


def test_mujoco_names_follow_the_four_finger_scheme() -> None:
    """Every name a tool reads on ias4f exists on ias3f too (per finger)."""
    m = PenHandPhysics.from_assets(hand="ias3f").model
    for f in get_hand("ias3f").fingers:
        for j in ("abd", "mcp", "pip"):
            m.joint(f"{f}_{j}")
            m.actuator(f"{f}_{j}")
        m.site(f"{f}_tip")
        m.geom(f"{f}_tip_collision")
        for s in ("touch", "pen_contact", "pen_force"):
            m.sensor(f"{f}_{s}")
    assert m.nu == 9 and mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "grasp") >= 0

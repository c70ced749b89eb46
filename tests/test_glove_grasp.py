"""IAS-GloveGrasp-v0: the glove scene, teleoperation, force display, the Gymnasium API."""

from __future__ import annotations

import math
import subprocess
import sys
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from ias_gym.envs.glove_grasp import GloveGraspEnv
from ias_gym.envs.glove_grasp_rewards import REWARD_TERMS
from ias_gym.glove import JOINT_NAMES, PersonParams, fit_linear, record_session
from ias_gym.glove.calibration import Calibration, GroupModel
from ias_gym.glove.device import ACTUATED_JOINTS
from ias_gym.glove.hand import THUMB_FLEXION_SHARES, hand_points
from ias_gym.glove.operator import pen_operator
from ias_gym.sim.glove_scene import INDEX_GEOMS, THUMB_GEOMS, load_glove_scene, thumb_coupling

PERSONS = ("p1", "p2", "p3")


@pytest.fixture(scope="module")
def person() -> PersonParams:
    return PersonParams.sample("p1")


@pytest.fixture(scope="module")
def linear_calibration(person: PersonParams) -> Calibration:
    """The linear baseline (numpy, fast): enough for API and force-display tests."""
    return fit_linear(record_session(person, 1000, seed=0))


@pytest.fixture()
def env(person: PersonParams, linear_calibration: Calibration) -> Any:
    e = GloveGraspEnv(person=person, calibration=linear_calibration)
    yield e
    e.close()


@pytest.mark.parametrize("person_id", PERSONS)
def test_scene_compiles_and_steps_under_noise(person_id: str) -> None:
    """Menagerie's test: every scene steps 1 s under random control without warnings."""
    person = PersonParams.sample(person_id)
    model = load_glove_scene(person)
    data = mujoco.MjData(model)
    assert [model.joint(n).name for n in JOINT_NAMES] == list(JOINT_NAMES)
    assert model.nu == len(JOINT_NAMES)
    for j in JOINT_NAMES:  # ctrlrange = joint range, from the same default class
        np.testing.assert_allclose(model.actuator(j).ctrlrange, model.joint(j).range)
    # Index and thumb segments have the person's lengths [m].
    mujoco.mj_forward(model, data)
    l3 = np.linalg.norm(data.site("index_tip").xpos - data.body("index_distal").xpos)
    assert math.isclose(l3, person.index_lengths[2], rel_tol=1e-9)
    rng = np.random.default_rng(0)
    lo, hi = model.actuator_ctrlrange.T
    for _ in range(100):  # 1 s in 10 ms blocks
        data.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_step(model, data, 10)
    assert np.isfinite(data.qpos).all()
    assert all(int(w.number) == 0 for w in data.warning), [w.number for w in data.warning]


def test_scale_changes_the_hand() -> None:
    small = PersonParams.nominal()
    model = load_glove_scene(small)
    big = load_glove_scene(PersonParams.sample("p2"))
    assert not np.allclose(model.body("index_middle").pos, big.body("index_middle").pos)


def test_api_info_and_reward_terms(env: GloveGraspEnv) -> None:
    obs, info = env.reset(seed=0)
    assert obs.shape == env.observation_space.shape
    keys = set(info)
    assert {"is_success", "feedback_torques", *(f"reward_{t}" for t in REWARD_TERMS)} <= keys
    for _ in range(5):
        obs, reward, _, _, info = env.step(env.action_space.sample())
        assert set(info) == keys
        assert reward == pytest.approx(sum(info[f"reward_{t}"] for t in REWARD_TERMS))
        assert info["feedback_torques"].shape == (len(ACTUATED_JOINTS),)
    # reset starts the force display, each step continues it
    assert env.glove is not None and len(env.glove.feedback) == 6  # type: ignore[attr-defined]


def test_nan_action_raises(env: GloveGraspEnv) -> None:
    env.reset(seed=0)
    action = np.zeros(10, dtype=np.float32)
    action[3] = np.nan
    with pytest.raises(ValueError, match="finite"):
        env.step(action)


def test_same_seed_same_episode(env: GloveGraspEnv) -> None:
    def run() -> np.ndarray:
        obs, _ = env.reset(seed=3)
        for _ in range(20):
            obs, *_ = env.step(np.zeros(10, dtype=np.float32))
        return obs

    np.testing.assert_array_equal(run(), run())


def test_force_display_zero_without_contact_and_grows_with_grip(
    person: PersonParams, linear_calibration: Calibration
) -> None:
    """tau = J^T f: exactly zero while no finger touches the pen, and growing with the grip
    (the pads' normal force) while they do: |tau| / f is a lever arm of the hand."""
    env = GloveGraspEnv(person=person, calibration=linear_calibration)
    env.reset(seed=0)
    forces, torques = [], []
    for _ in range(80):  # the pinch closes over these 0.8 s
        _, _, terminated, _, info = env.step(np.zeros(10, dtype=np.float32))
        tau = info["feedback_torques"]
        if not (info["index_contact"] or info["thumb_contact"]):
            assert np.all(tau == 0.0)
        elif info["pinch_force"] > 0.05:
            forces.append(info["pinch_force"])
            torques.append(float(np.linalg.norm(tau)))
        if terminated:
            break
    env.close()
    f, t = np.array(forces), np.array(torques)
    assert len(f) >= 5
    lever = t / f  # [m]
    assert np.all((lever > 0.002) & (lever < 0.2)), lever
    assert t[np.argmax(f)] > t[np.argmin(f)]
    assert np.corrcoef(f, t)[0, 1] > 0.7


def test_check_env(env: GloveGraspEnv) -> None:
    check_env(env, skip_render_check=True)


def _lift_successes(person: PersonParams, calibration: Calibration, seeds: int = 10) -> int:
    """Episodes (seeds 0..seeds-1, zero action = pure teleoperation) that end lifted."""
    env = GloveGraspEnv(person=person, calibration=calibration)
    successes = 0
    for seed in range(seeds):
        env.reset(seed=seed)
        while True:
            *_, terminated, truncated, info = env.step(np.zeros(10, dtype=np.float32))
            if terminated or truncated:
                break
        successes += bool(info["is_success"])
    env.close()
    return successes


def test_teleoperated_lift_with_ann_calibration(person: PersonParams) -> None:
    """The scripted operator, seen through the glove and the person's ANN calibration,
    pinches and lifts the pen (>= 3 cm, held at the end) in >= 9 of 10 episodes."""
    pytest.importorskip("torch")
    from ias_gym.glove.training import calibrate_person

    ann = calibrate_person(person).models["ann"]
    assert _lift_successes(person, ann) >= 9


def test_teleoperated_lift_with_linear_calibration(
    person: PersonParams, linear_calibration: Calibration
) -> None:
    """The linear baseline (measured 10/10 for p1 too, see the report)."""
    assert _lift_successes(person, linear_calibration) >= 9


def test_pickling_is_refused_with_a_clear_message() -> None:
    import pickle

    import gymnasium as gym

    env = gym.make("IAS-GloveGrasp-v0")
    with pytest.raises(TypeError, match="live glove device"):
        pickle.dumps(env.unwrapped)


def test_evaluate_runs_the_glove_env_by_teleoperation() -> None:
    from ias_gym.evaluation import evaluate_spec

    result = evaluate_spec("IAS-GloveGrasp-v0", "teleop", episodes=1)
    summary = result.summary()
    assert summary["success_rate"] == 1.0 and summary["pen_height_max_mm"] >= 30.0
    with pytest.raises(ValueError, match="has no expert"):
        evaluate_spec("IAS-GloveGrasp-v0", "expert", episodes=1)
    with pytest.raises(ValueError, match="needs a glove env"):
        evaluate_spec("IAS-PenSlide-v0", "teleop", episodes=1)


def _absurd_calibration(calibration: Calibration) -> Calibration:
    """``calibration`` with the other fingers' group replaced by a network of 1e308 weights
    (finite, so a Calibration accepts it): its folded weights overflow and every predicted
    joint angle is NaN, as with the 1e308 profile seen in the field."""
    g = calibration.group("fingers")
    huge = (np.full((2, 2), 1e308), np.zeros(2)), (np.eye(2), np.zeros(2))
    bad = GroupModel(g.name, "ann", g.inputs, g.outputs, g.x_mean, g.x_scale, g.y_mean,
                     g.y_scale, huge)  # fmt: skip
    return Calibration(tuple(bad if x.name == "fingers" else x for x in calibration.groups))


@pytest.mark.filterwarnings("ignore:overflow:RuntimeWarning", "ignore:invalid:RuntimeWarning")
def test_nonfinite_calibration_never_reaches_mujoco(
    person: PersonParams, linear_calibration: Calibration
) -> None:
    """A calibration that turns readings into NaN mid-episode: the targets MuJoCo gets stay
    finite (no 'Nan, Inf or huge value in CTRL'), the step reports a fault and truncates.
    Before, NaN reached ctrl, MuJoCo warned and zeroed it (a limp hand) and nothing said so."""
    absurd = _absurd_calibration(linear_calibration)
    assert np.isnan(absurd.predict(np.zeros(10))).all()
    env = GloveGraspEnv(person=person, calibration=linear_calibration)
    env.reset(seed=0)
    for _ in range(5):
        env.step(np.zeros(10, dtype=np.float32))
    held = env.data.ctrl.copy()
    env.calibration = absurd  # the calibration breaks mid-episode
    obs, _, terminated, truncated, info = env.step(np.zeros(10, dtype=np.float32))
    assert np.isfinite(env.data.ctrl).all() and np.isfinite(obs).all()
    assert [int(w.number) for w in env.data.warning] == [0] * len(env.data.warning)
    assert "non-finite joint angles" in info["fault"] and truncated and not terminated
    # the last finite targets are held (low-passed Θ: within the filter's step of them)
    np.testing.assert_allclose(env.data.ctrl, held, atol=0.05)

    # Broken from the first reading: reset holds a finite pose and the first step ends it.
    env.calibration = absurd
    obs, info = env.reset(seed=1)
    assert np.isfinite(obs).all() and "non-finite" in info["fault"]
    *_, truncated, info = env.step(np.zeros(10, dtype=np.float32))
    assert truncated and "non-finite" in info["fault"] and np.isfinite(env.data.ctrl).all()
    env.close()


def test_diverging_simulation_is_reported_and_truncated(env: GloveGraspEnv) -> None:
    """MuJoCo's warning counters are watched as in the pen tasks: a blow-up (here a pen
    velocity above MuJoCo's 1e10 limit, which makes it warn and reset its data) gives
    ``info["sim_unstable"]`` and truncation, with a finite observation; a normal step
    reports it False."""
    _, info = env.reset(seed=0)
    assert info["sim_unstable"] is False
    *_, info = env.step(np.zeros(10, dtype=np.float32))
    assert info["sim_unstable"] is False
    env.data.qvel[env._pen_v : env._pen_v + 3] = 1e12
    obs, _, terminated, truncated, info = env.step(np.zeros(10, dtype=np.float32))
    assert info["sim_unstable"] is True and truncated and not terminated
    assert np.isfinite(obs).all()
    assert sum(int(w.number) for w in env.data.warning) > 0


def test_pen_operator_opens_the_pinch_by_the_pen_it_is_given(person: PersonParams) -> None:
    """The operator's pinch takes the pen's radius from its caller (the scene's model): a pen
    2 mm thicker opens the pinch's tips 4 mm wider; a radius <= 0 is refused."""
    tips = []
    for radius in (0.01, 0.012):
        index, thumb = hand_points(pen_operator(person, radius).poses["pinch"], person)
        tips.append(float(np.linalg.norm(index[-1] - thumb[-1])))
    assert tips[1] - tips[0] == pytest.approx(0.004, abs=1e-9)
    with pytest.raises(ValueError, match="pen_radius"):
        pen_operator(person, 0.0)


def test_glove_layer_imports_no_physics() -> None:
    """The operator and the profile cache sit below sim/ and envs/: importing them loads no
    MuJoCo (the layer order of the package)."""
    code = (
        "import sys, ias_gym.glove.operator, ias_gym.glove.profile_cache; "
        "bad = [m for m in ('mujoco', 'ias_gym.sim', 'ias_gym.envs') if m in sys.modules]; "
        "sys.exit(str(bad) if bad else 0)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_thumb_coupling_is_read_from_the_model(env: GloveGraspEnv) -> None:
    """The thumb's passive hinges follow thumb_flexion by the model's equalities (the ratio
    of the glove's planar thumb), and reset places them there; a coupling the env cannot
    fold into the force display (not linear) is refused."""
    model = load_glove_scene()
    joints, ratios = thumb_coupling(model)
    assert sorted(model.joint(j).name for j in joints) == ["thumb_ip", "thumb_mcp_share"]
    np.testing.assert_array_equal(ratios, THUMB_FLEXION_SHARES[1])
    model.eq_data[0, 1] = 0.3
    assert 0.3 in thumb_coupling(model)[1]
    model.eq_data[0, 2] = 0.1  # quadratic term
    with pytest.raises(ValueError, match="non-linearly"):
        thumb_coupling(model)

    env.reset(seed=0)
    q = env.data.qpos
    flexion = q[env.model.jnt_qposadr[env.model.joint("thumb_flexion").id]]
    for j, ratio in zip(*thumb_coupling(env.model), strict=True):
        assert q[env.model.jnt_qposadr[j]] == ratio * flexion


def test_one_pass_over_the_contacts_feeds_force_display_and_skill_model(
    env: GloveGraspEnv, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Each step reads every finger-pen contact force once: the env's pass gives the force
    display and the recorder's W and c (before, both walked the contacts; measured 2 reads
    per contact). The recorder's c is that of a fresh pass over the same state."""
    from ias_gym.skills.glove_session import GloveSkillModelRecorder

    calls = 0
    contact_force = mujoco.mj_contactForce

    def counting(*args: Any) -> None:
        nonlocal calls
        calls += 1
        contact_force(*args)

    monkeypatch.setattr(mujoco, "mj_contactForce", counting)
    recorder = GloveSkillModelRecorder()
    env.reset(seed=0)
    recorder.sample(env)
    finger_geoms = {env.model.geom(n).id for n in (*INDEX_GEOMS, *THUMB_GEOMS)}
    pen = env.model.geom("pen").id
    touched = 0
    for _ in range(100):  # through the pinch's close
        calls = 0
        env.step(np.zeros(10, dtype=np.float32))
        recorder.sample(env)
        n = sum(
            (int(a) == pen and int(b) in finger_geoms) or (int(b) == pen and int(a) in finger_geoms)
            for a, b in env.data.contact.geom
        )
        assert calls == n
        touched += n > 0
    assert touched > 50
    fresh = env.physics.finger_contacts()
    np.testing.assert_array_equal(recorder.model().c[-1], env.physics.contact_intensities(fresh))


def test_the_observation_layout_names_every_column() -> None:
    """Consumers index the glove observation by name: the parts tile it, and each holds what
    its name says (time, the pen's height, the force display; the assist env's upcoming
    targets after the glove world's parts)."""
    for env_id, extra in (
        ("IAS-GloveGrasp-v0", {}),
        ("IAS-GloveAssist-v0", {"skill": "lift_hold"}),
    ):
        env = gym.make(env_id, **extra)
        unwrapped = env.unwrapped
        layout = unwrapped.observation_layout
        columns = sorted(i for s in layout.values() for i in range(s.start, s.stop))
        assert columns == list(range(env.observation_space.shape[0]))
        obs, info = env.reset(seed=0)
        for step in range(1, 4):
            obs, _, _, _, info = env.step(np.zeros(10, dtype=np.float32))
            assert obs[layout["time"]][0] == pytest.approx(step * unwrapped.dt)
            assert obs[layout["pen_position"]][2] == pytest.approx(info["pen_height"])
            np.testing.assert_array_equal(obs[layout["feedback_torques"]], info["feedback_torques"])
            if "upcoming_theta" in layout:
                np.testing.assert_array_equal(
                    obs[layout["upcoming_theta"]], unwrapped.upcoming_theta
                )
        env.close()

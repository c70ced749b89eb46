"""The scenes' physical constants that code outside the MJCF needs, read from the compiled model.

The friction a controller assumes, the friction and torsion with which a demonstration's grasp
margin is computed, the glove pen's radius: each is read once from the compiled scene it
belongs to, never copied, so that editing ``pen.xml`` or ``human_hand.xml`` changes every
user. A pen contact's friction follows MuJoCo's rule for a geom pair
(:func:`pair_friction`): the geom of higher ``priority`` sets it, else the larger of the two.

These are the scenes' nominal values: an env that scales its friction as a disturbance
(``friction_scale``) does not change them, as a controller designed for the nominal pen would
not know the disturbed one.
"""

from __future__ import annotations

import functools
import importlib.resources

import mujoco
import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

#: The robot pen tasks' scene and the glove world's scene (``ias_gym.assets``).
PEN_SCENE = "scene_pen.xml"
GLOVE_SCENE = "scene_glove.xml"
#: The geoms whose contact sets the friction of each scene's pen contacts: the pen, and a
#: fingertip of the robot hand / the glove hand's index pad (the thumb's pad is of its class).
PEN_GEOM = "pen"
ROBOT_TIP_GEOM = "f1_tip_collision"
GLOVE_PAD_GEOM = "index_pad"


def _compile(scene: str) -> mujoco.MjModel:
    resource = importlib.resources.files("ias_gym.assets") / scene
    # The scenes include the hand and pen files by relative path: compile from disk.
    with importlib.resources.as_file(resource) as path:
        return mujoco.MjModel.from_xml_path(str(path))


def pair_friction(model: mujoco.MjModel, geom1: str, geom2: str) -> FloatArray:
    """The friction ``(sliding, torsional, rolling)`` of a contact between two geoms.

    MuJoCo's rule for a geom pair (no explicit ``<pair>``): the geom with the higher
    ``priority`` sets the contact's friction; at equal priority each coefficient is the
    larger of the two geoms'.
    """
    a = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, geom1)
    b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, geom2)
    if a < 0 or b < 0:
        missing = geom1 if a < 0 else geom2
        raise ValueError(f"the scene has no geom named {missing!r}")
    pa, pb = int(model.geom_priority[a]), int(model.geom_priority[b])
    if pa != pb:
        return np.array(model.geom_friction[a if pa > pb else b], dtype=float)
    return np.maximum(model.geom_friction[a], model.geom_friction[b]).astype(float)


@functools.cache
def pen_friction() -> float:
    """Sliding friction coefficient of the robot pen tasks' pen contacts [-] (``pen.xml``)."""
    return float(pair_friction(_compile(PEN_SCENE), PEN_GEOM, ROBOT_TIP_GEOM)[0])


@functools.cache
def glove_pad_friction() -> tuple[float, float]:
    """The glove world's pen contacts: sliding coefficient [-] and torsional friction [m].

    The glove hand's pads (``human_hand.xml``, class ``pad``, condim 4) win every pen
    contact by priority, so theirs are the contacts' coefficients.
    """
    friction = pair_friction(_compile(GLOVE_SCENE), PEN_GEOM, GLOVE_PAD_GEOM)
    return float(friction[0]), float(friction[1])


@functools.cache
def glove_pen_radius() -> float:
    """The radius of the glove world's pen [m] (``scene_glove.xml``)."""
    model = _compile(GLOVE_SCENE)
    return float(model.geom_size[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, PEN_GEOM)][0])

"""The LEAP hand as a pen hand, loaded from MuJoCo Playground's installed package.

The LEAP hand (Shaw, Agarwal & Pathak, RSS 2023) is a low-cost, 16-joint hand that many
labs build. Its MJCF (``mujoco_playground/_src/manipulation/leap_hand/xmls/leap_rh_mjx.xml``,
Apache-2.0) is read from the installed ``playground`` package (``pip install --no-deps
playground==0.2.0``: its own dependencies pull jax and brax, which this package never
imports; the package is found with :func:`importlib.util.find_spec`, not imported). The wheel
does not ship the hand's meshes, but every mesh geom is visual only (``contype`` and
``conaffinity`` 0) and collision is boxes, so the meshes and their geoms are deleted with
:class:`mujoco.MjSpec` and the physics is the model's. Dressed in code as a pen hand of the
conventions of :mod:`ias_gym.sim.pen_hand`:

- the hand is fixed to the world at a placement solved once (``train/place_hand.py --hand leap
  --layout two-under --steepness-axis tip --steepness 0.1 --thumb-steepness 0.3 --starts 6``:
  the palm faces up below the pen, the index and middle finger curl up under it, the thumb
  reaches over it with its rounded end pointing into the pen); the fingers that do not hold
  the pen (the ring finger) and the thumb's axial joint keep their joint at zero (the joint
  is removed);
- three fingers hold the pen: the index below at x = +2.25 cm (``f1``), the thumb on top at
  the centre (``f2``), the middle finger below at x = -2.25 cm (``f3``): two fingers carry
  the pen's weight, not the thumb's three motors alone;
- each finger has three driven joints ``abd``, ``mcp``, ``pip`` (the model's ``rot``,
  ``mcp``, ``pip``; the thumb's ``cmc``, ``mcp``, ``ipl``) with a torque motor of the model's
  actuator force range (0.2196 N m, 60 % of the servo's stall torque, the model's note).
  The fingers' distal joint is driven in the real hand; here a joint equality couples it to
  the middle joint, ``dip = 0.7 pip`` (:data:`LEAP_COUPLING`, about the human finger's
  coupling), so that each finger has the three joints the grasp law drives for a 3-D tip
  force. The model's joint damping (0.2 N m s) and friction loss (0.02 N m) are kept;
- the fingertip's contact geom is the rounded tip that the model's own file gives as the
  alternative to its box (a capsule of radius 12 mm, commented out there): on a box, the
  contact point with the pen jumps between the box's edges as the pen turns, which the
  grasp model (smooth contact points, eq. 11) does not have;
- each holding finger gets the sensors every pen hand has (``fN_tip``, ``fN_tip_collision``,
  ``fN_touch``, ``fN_pen_contact``, ``fN_pen_force``) and the keyframe ``grasp``.

Paper frame as everywhere (x along the pen, y up, z lateral), SI units.
"""

from __future__ import annotations

import importlib.resources
import importlib.util
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from ias_gym.errors import InputError
from ias_gym.sim.hand_dressing import (
    DRIVEN,
    add_grasp_key,
    add_tip_site,
    couple_distal,
    drive_joint,
)
from ias_gym.sim.pen_sensors import EXTRA, add_pen_sensors

__all__ = [
    "LEAP_COUPLING",
    "LEAP_FINGERS",
    "LEAP_GRASP",
    "LEAP_MOUNT",
    "LeapFinger",
    "build_leap_scene",
    "leap_model_path",
    "leap_spec",
]


@dataclass(frozen=True)
class LeapFinger:
    """One finger of the LEAP hand as a pen finger.

    Attributes:
        name: our prefix (``f1``, ...).
        joints: the model's joints driven as ``abd``, ``mcp``, ``pip``.
        dip: the model's distal joint coupled to ``pip`` (``None``: no coupling).
        distal: the model's distal body; tip: its contact geom (a box in the model).
        capsule: the rounded tip's position [m] in the distal body and its half-length
            [m] (the model file's commented capsule), along the body's -y.
    """

    name: str
    joints: tuple[str, str, str]
    dip: str | None
    distal: str
    tip: str
    capsule: tuple[tuple[float, float, float], float]


#: The rounded tip's radius [m] (the model file's commented capsule).
TIP_RADIUS = 0.012
_FINGER_TIP = ((0.0, -0.03, 0.015), 0.008)
_THUMB_TIP = ((0.0, -0.04, -0.015), 0.008)
#: The holding fingers, in the pen hand's order.
LEAP_FINGERS: tuple[LeapFinger, ...] = (
    LeapFinger(
        "f1",
        ("if_rot", "if_mcp", "if_pip"),
        "if_dip",
        "if_ds",
        "if_tip",
        ((0, -0.03, 0.015), 0.008),
    ),
    LeapFinger(
        "f2", ("th_cmc", "th_mcp", "th_ipl"), None, "th_ds", "th_tip", ((0, -0.04, -0.015), 0.008)
    ),
    LeapFinger(
        "f3",
        ("mf_rot", "mf_mcp", "mf_pip"),
        "mf_dip",
        "mf_ds",
        "mf_tip",
        ((0, -0.03, 0.015), 0.008),
    ),
)
#: The distal joint's angle per middle-joint angle (a design choice of this scene: the real
#: hand drives both; the human finger couples them at about 2/3).
LEAP_COUPLING = 0.7
#: The hand's placement: the model's ``leap_mount`` body's position [m] and orientation
#: (w, x, y, z) in MuJoCo's world, solved by ``train/place_hand.py --hand leap``.
LEAP_MOUNT: tuple[tuple[float, float, float], tuple[float, float, float, float]] = (
    (-0.019598575, -0.138348979, 0.191160243),
    (0.708094616, -0.073506114, 0.043744301, 0.700917471),
)
#: The grasp keyframe's driven joint angles per finger (abd, mcp, pip) [rad], from the same
#: script (tips 0.3 mm inside the pen at x = +2.25, 0, -2.25 cm).
LEAP_GRASP: tuple[tuple[float, float, float], ...] | None = (
    (0.104780478, 0.325883197, 1.650980189),
    (1.674270301, 0.091558939, 1.275154135),
    (0.129919365, 0.360963049, 1.630572189),
)
#: Joints removed (their bodies stay at the joint's zero): the ring finger's, the thumb's
#: axial joint.
_FIXED_JOINTS = ("rf_mcp", "rf_rot", "rf_pip", "rf_dip", "th_axl")
#: The prefix of the hand's names in the scene.
_SCENE_PREFIX = "leap/"
_MODEL = "_src/manipulation/leap_hand/xmls/leap_rh_mjx.xml"


def leap_model_path() -> Path:
    """The installed MuJoCo Playground's LEAP hand MJCF.

    Raises:
        InputError: the package is not installed (the message names the install command).
    """
    found = importlib.util.find_spec("mujoco_playground")
    path = None
    if found is not None and found.submodule_search_locations:
        path = Path(next(iter(found.submodule_search_locations))) / _MODEL
    if path is None or not path.is_file():
        raise InputError(
            "the LEAP hand needs MuJoCo Playground's model; install it with "
            f"pip install --no-deps playground==0.2.0 (or pip install 'ias-gym[{EXTRA}]' "
            "and then that command; make setup does both)"
        )
    return path


def _leap_source_spec() -> mujoco.MjSpec:
    """The LEAP hand as its package ships it, without its (absent) meshes."""
    spec = mujoco.MjSpec.from_string(leap_model_path().read_text())
    for geom in list(spec.geoms):
        if geom.type == mujoco.mjtGeom.mjGEOM_MESH:
            spec.delete(geom)
    for mesh in list(spec.meshes):
        spec.delete(mesh)
    for light in list(spec.lights):
        spec.delete(light)
    for geom in spec.geoms:  # the collision boxes in a group the viewer shows (no meshes)
        geom.group, geom.rgba = 2, [0.25, 0.25, 0.28, 1.0]
    return spec


def leap_spec(
    mount: tuple[tuple[float, float, float], tuple[float, float, float, float]] = LEAP_MOUNT,
    grasp: tuple[tuple[float, float, float], ...] | None = LEAP_GRASP,
) -> mujoco.MjSpec:
    """The pen scene with the LEAP hand as a pen hand (not compiled).

    Args:
        mount: the hand mount's position [m] and quaternion (w, x, y, z) in the world.
        grasp: the driven joints' angles of the ``grasp`` keyframe, per finger; ``None``
            adds no keyframe (the placement script solves for it).

    Raises:
        InputError: MuJoCo Playground is not installed.
    """
    hand = _leap_source_spec()
    force = {j.name: float(j.actfrcrange[1]) for j in hand.joints}
    for actuator in list(hand.actuators):
        hand.delete(actuator)
    for name in _FIXED_JOINTS:
        hand.delete(hand.joint(name))
    body = hand.body("leap_mount")
    body.pos = np.asarray(mount[0], dtype=float)
    body.quat = np.asarray(mount[1], dtype=float)

    resource = importlib.resources.files("ias_gym.assets") / "scene_pen_external.xml"
    with importlib.resources.as_file(resource) as path:
        scene = mujoco.MjSpec.from_file(str(path))
    # the scene's solver options, not the model's (made for a 10 ms MJX step)
    for option in ("timestep", "iterations", "ls_iterations", "integrator", "disableflags"):
        setattr(hand.option, option, getattr(scene.option, option))
    scene.worldbody.add_frame().attach_body(body, _SCENE_PREFIX, "")
    for finger in LEAP_FINGERS:
        for suffix, source in zip(DRIVEN, finger.joints, strict=True):
            drive_joint(scene, _SCENE_PREFIX + source, f"{finger.name}_{suffix}", force[source])
        if finger.dip is not None:
            couple_distal(scene, _SCENE_PREFIX + finger.dip, finger.name, LEAP_COUPLING)
        box = scene.geom(_SCENE_PREFIX + finger.tip)
        friction, solref, solimp = list(box.friction), list(box.solref), list(box.solimp)
        scene.delete(box)
        distal = scene.body(_SCENE_PREFIX + finger.distal)
        (x, y, z), half = finger.capsule
        distal.add_geom(
            name=f"{finger.name}_tip_collision",
            type=mujoco.mjtGeom.mjGEOM_CAPSULE,
            size=[TIP_RADIUS, half, 0.0],
            pos=[x, y, z],
            quat=[1.0, 1.0, 0.0, 0.0],  # the capsule's axis along the body's -y
            friction=friction,
            solref=solref,
            solimp=solimp,
            rgba=[0.5, 0.5, 0.5, 1.0],
        )
        add_tip_site(distal, finger.name, [x, y - half, z], TIP_RADIUS)  # the end's centre
    add_pen_sensors(scene, [finger.name for finger in LEAP_FINGERS])
    if grasp is not None:
        add_grasp_key(scene, LEAP_FINGERS, grasp, LEAP_COUPLING)
    return scene


def build_leap_scene() -> mujoco.MjModel:
    """Compile the LEAP hand's pen scene (:func:`leap_spec`)."""
    return leap_spec().compile()

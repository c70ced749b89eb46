"""Robot hands that other projects built, loaded from their installed packages as pen hands.

The Shadow Dexterous Hand is the model behind Gymnasium-Robotics' Adroit and HandManipulate
tasks. Its MJCF (``envs/assets/hand/robot.xml`` with ``shared.xml``, ``shared_asset.xml``
and the meshes of ``envs/assets/stls/hand``; MIT, with Shadow's Apache-2.0 notice kept in
the package's ``LICENSE.md``) is read from the installed ``gymnasium-robotics``
(``pip install 'ias-gym[hands]'``), never copied into this repository, and dressed in code
(:func:`build_shadow_scene`, with :class:`mujoco.MjSpec`) as a pen hand of the conventions
of :mod:`ias_gym.sim.pen_hand`:

- the hand is fixed to the world at a placement solved once (``train/place_hand.py --hand shadow``:
  the palm faces the pen, the fingers point up and curl over it); its wrist joints are
  removed, as are the joints of the fingers that do not touch the pen (middle and ring
  finger, the little finger's metacarpal joint), which stay straight;
- three fingers hold the pen, as on ``ias3f``: the first finger on top at x = -3.5 cm
  (``f1``), the thumb below the centre (``f2``), the little finger on top at x = +4 cm
  (``f3``; nearer the centre it would press against the ring finger beside it);
- each finger has three driven joints ``abd``, ``mcp``, ``pip`` with a torque motor whose
  range is the force range of the model's own actuator of that joint. The fingers' distal
  joint J0 is not driven: in the model a tendon couples it to the middle joint J1 (the real
  hand's underactuated last joint), kept here as a joint equality ``dip = 1.142 pip`` (the
  ratio of that tendon's two coefficients, 0.00805 / 0.00705). The thumb's five joints are
  independent in the model; the law drives three of them (THJ4 ``abd``, THJ3 ``mcp``, THJ0
  ``pip``) and the two others (THJ2, THJ1) are fixed at zero, where the grasp does not need
  them;
- each holding finger gets the sensors every pen hand has: the tip site ``fN_tip`` (the
  centre of its distal capsule's end), the contact geom ``fN_tip_collision`` (the distal
  capsule), ``fN_touch``, ``fN_pen_contact`` and ``fN_pen_force``; the keyframe ``grasp``.

Paper frame as everywhere (x along the pen, y up, z lateral), SI units.
"""

from __future__ import annotations

import importlib.resources
import importlib.util
from collections.abc import Callable, Sequence
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
from ias_gym.sim.leap_hand import build_leap_scene
from ias_gym.sim.pen_sensors import EXTRA, add_pen_sensors

__all__ = [
    "BUILDERS",
    "SHADOW_COUPLING",
    "SHADOW_FINGERS",
    "SHADOW_GRASP",
    "SHADOW_MOUNT",
    "ShadowFinger",
    "build_shadow_scene",
    "coupled_joints",
    "shadow_package_dir",
    "shadow_spec",
]


@dataclass(frozen=True)
class ShadowFinger:
    """One finger of the Shadow hand as a pen finger.

    Attributes:
        name: our prefix (``f1``, ...).
        joints: the model's joints driven as ``abd``, ``mcp``, ``pip``.
        dip: the model's distal joint coupled to ``pip`` (``None``: no coupling).
        distal: the model's distal body, whose capsule is the finger's contact geom.
    """

    name: str
    joints: tuple[str, str, str]
    dip: str | None
    distal: str


#: The holding fingers, in the pen hand's order.
SHADOW_FINGERS: tuple[ShadowFinger, ...] = (
    ShadowFinger("f1", ("FFJ3", "FFJ2", "FFJ1"), "FFJ0", "ffdistal"),
    ShadowFinger("f2", ("THJ4", "THJ3", "THJ0"), None, "thdistal"),
    ShadowFinger("f3", ("LFJ3", "LFJ2", "LFJ1"), "LFJ0", "lfdistal"),
)
#: The distal joint's angle per middle-joint angle: the model's coupling tendon
#: ``T_FFJ1c`` holds ``0.00705 J0 - 0.00805 J1`` within +-1 mm, so J0 = 1.142 J1.
SHADOW_COUPLING = 0.00805 / 0.00705
#: The hand's placement: the model's ``hand mount`` body's position [m] and orientation
#: (w, x, y, z) in MuJoCo's world, solved by ``train/place_hand.py --hand shadow``.
SHADOW_MOUNT: tuple[tuple[float, float, float], tuple[float, float, float, float]] = (
    (0.122254662, -0.146767647, -0.161410413),
    (0.040476884, -0.151935972, 0.122124468, 0.979980967),
)
#: The grasp keyframe's driven joint angles per finger (abd, mcp, pip) [rad], from the same
#: script (tips 0.3 mm inside the pen at x = -3.5, 0, +4 cm).
SHADOW_GRASP: tuple[tuple[float, float, float], ...] = (
    (0.134828200, 0.113960124, 0.899646515),
    (0.610745535, 1.119216581, -0.938385092),
    (0.063399706, 0.352817655, 0.937463272),
)
#: Joints removed (their bodies stay at the joint's zero): the wrist, the fingers that do
#: not hold the pen, the little finger's metacarpal and the thumb's two joints not driven.
_FIXED_JOINTS = (
    "WRJ1",
    "WRJ0",
    "MFJ3",
    "MFJ2",
    "MFJ1",
    "MFJ0",
    "RFJ3",
    "RFJ2",
    "RFJ1",
    "RFJ0",
    "LFJ4",
    "THJ2",
    "THJ1",
)
_PREFIX = "robot0:"
#: The prefix of the hand's names in the scene.
_SCENE_PREFIX = "shadow/"


def shadow_package_dir() -> Path:
    """The installed Gymnasium-Robotics' ``envs/assets`` folder.

    Raises:
        InputError: the package is not installed (the message names the extra).
    """
    found = importlib.util.find_spec("gymnasium_robotics")
    if found is None or not found.submodule_search_locations:
        raise InputError(
            "the Shadow hand needs gymnasium-robotics; install it with "
            f"pip install 'ias-gym[{EXTRA}]'"
        )
    return Path(next(iter(found.submodule_search_locations))) / "envs" / "assets"


def _shadow_source_spec() -> mujoco.MjSpec:
    """The Shadow hand as its package ships it (defaults, meshes, bodies, contact pairs)."""
    root = shadow_package_dir()
    files = {p.name: p.read_bytes() for p in (root / "hand").glob("*.xml")}
    meshes = {p.name: p.read_bytes() for p in (root / "stls" / "hand").glob("*.stl")}
    xml = """<mujoco model="shadow_hand">
      <compiler angle="radian" coordinate="local"/>
      <include file="shared.xml"/>
      <asset><include file="shared_asset.xml"/></asset>
      <worldbody><include file="robot.xml"/></worldbody>
    </mujoco>"""
    spec = mujoco.MjSpec.from_string(xml, files)
    spec.assets = meshes
    return spec


def shadow_spec(
    mount: tuple[tuple[float, float, float], tuple[float, float, float, float]] = SHADOW_MOUNT,
    grasp: tuple[tuple[float, float, float], ...] | None = SHADOW_GRASP,
) -> mujoco.MjSpec:
    """The pen scene with the Shadow hand as a pen hand (not compiled).

    Args:
        mount: the hand mount's position [m] and quaternion (w, x, y, z) in the world.
        grasp: the driven joints' angles of the ``grasp`` keyframe, per finger; ``None``
            adds no keyframe (the placement script solves for it).

    Raises:
        InputError: gymnasium-robotics is not installed.
    """
    hand = _shadow_source_spec()
    # each driven joint's force range in the model's own actuators [N m] (shared.xml)
    ranges = {a.target.removeprefix(_PREFIX): float(a.forcerange[1]) for a in hand.actuators}
    for actuator in list(hand.actuators):
        hand.delete(actuator)
    for element in [*hand.tendons, *hand.sensors]:  # made for the whole hand's joints
        hand.delete(element)
    for name in _FIXED_JOINTS:
        hand.delete(hand.joint(_PREFIX + name))
    body = hand.body(_PREFIX + "hand mount")
    body.pos = np.asarray(mount[0], dtype=float)
    body.quat = np.asarray(mount[1], dtype=float)
    body.alt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT

    resource = importlib.resources.files("ias_gym.assets") / "scene_pen_external.xml"
    with importlib.resources.as_file(resource) as path:
        scene = mujoco.MjSpec.from_file(str(path))
    # the model's own physics step (2 ms, as Gymnasium-Robotics runs this hand): measured
    # with the expert and the transfers, docs/hands.md
    scene.option.timestep = hand.option.timestep
    # the model's size hints (njmax, nconmax, user fields) are the scene's: MuJoCo sizes itself
    for size in ("njmax", "nconmax"):
        setattr(hand, size, -1)
    for size in ("nuser_jnt", "nuser_site", "nuser_tendon", "nuser_actuator", "nuser_sensor"):
        setattr(hand, size, -1)
    scene.worldbody.add_frame().attach_body(body, _SCENE_PREFIX, "")
    scene.assets = dict(hand.assets)  # the meshes, read from the package
    _dress(scene, ranges)
    if grasp is not None:
        add_grasp_key(scene, SHADOW_FINGERS, grasp, SHADOW_COUPLING)
    return scene


def _dress(scene: mujoco.MjSpec, ranges: dict[str, float]) -> None:
    """Rename the holding fingers' joints, add their motors (``ranges``: force range per
    source joint [N m]), couplings, sites and sensors."""
    for finger in SHADOW_FINGERS:
        for suffix, source in zip(DRIVEN, finger.joints, strict=True):
            drive_joint(
                scene, _SCENE_PREFIX + _PREFIX + source, f"{finger.name}_{suffix}", ranges[source]
            )
        # the finger's base moves against the palm, now fixed to the world: MuJoCo's
        # filter of parent-child contacts leaves out bodies on the world, so the model's
        # own exclusion (its thumb base's box sits inside the palm) is made explicit
        base = scene.joint(f"{finger.name}_abd").parent
        scene.add_exclude(bodyname1=base.parent.name, bodyname2=base.name)
        if finger.dip is not None:
            couple_distal(scene, _SCENE_PREFIX + _PREFIX + finger.dip, finger.name, SHADOW_COUPLING)
        capsule = scene.geom(_SCENE_PREFIX + _PREFIX + f"C_{finger.distal}")
        old, capsule.name = capsule.name, f"{finger.name}_tip_collision"
        for pair in scene.pairs:  # the model's finger-finger contact pairs name it
            pair.geomname1 = capsule.name if pair.geomname1 == old else pair.geomname1
            pair.geomname2 = capsule.name if pair.geomname2 == old else pair.geomname2
        distal = scene.body(_SCENE_PREFIX + _PREFIX + finger.distal)
        radius, half = float(capsule.size[0]), float(capsule.size[1])
        centre = np.asarray(capsule.pos, dtype=float) + np.array([0.0, 0.0, half])
        add_tip_site(distal, finger.name, centre, radius)
    add_pen_sensors(scene, [finger.name for finger in SHADOW_FINGERS])


def build_shadow_scene() -> mujoco.MjModel:
    """Compile the Shadow hand's pen scene (:func:`shadow_spec`)."""
    return shadow_spec().compile()


def coupled_joints(model: mujoco.MjModel, joints: Sequence[int]) -> list[tuple[int, int, float]]:
    """The joints tied to a hand joint by an active linear joint equality (a distal joint
    coupled to its middle one, as the Shadow and LEAP scenes have).

    Returns ``(follower dof, index of the leader in joints, ratio)`` per joint equality
    ``follower = ratio * leader`` whose leader is one of ``joints`` and whose follower is
    not (MuJoCo's ``mjEQ_JOINT`` with ``polycoef = [0, ratio, 0, 0, 0]``).

    Raises:
        ValueError: such an equality is not linear through zero (not supported).
    """
    index = {int(j): i for i, j in enumerate(joints)}
    out = []
    for e in range(model.neq):
        if model.eq_type[e] != mujoco.mjtEq.mjEQ_JOINT or not model.eq_active0[e]:
            continue
        follower, leader = int(model.eq_obj1id[e]), int(model.eq_obj2id[e])
        if leader not in index or follower in index:
            continue
        coef = model.eq_data[e, :5]
        if coef[0] != 0.0 or np.any(coef[2:] != 0.0):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, follower)
            raise ValueError(f"joint {name!r}: only a linear coupling through zero is supported")
        out.append((int(model.jnt_dofadr[follower]), index[leader], float(coef[1])))
    return out


#: Scene builders by the name a :class:`~ias_gym.sim.hands.HandSpec` gives as its scene.
BUILDERS: dict[str, Callable[[], mujoco.MjModel]] = {
    "shadow": build_shadow_scene,
    "leap": build_leap_scene,
}

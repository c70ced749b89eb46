"""Dressing a robot hand's model as a pen hand: what every external hand's scene adds.

An external hand (Shadow, LEAP) comes with its own names, actuators and keyframes. The pen
tasks address a hand by the names of :mod:`ias_gym.sim.pen_hand`: per holding finger the
joints ``NAME_abd``, ``NAME_mcp``, ``NAME_pip`` (and a coupled ``NAME_dip``), a torque motor
``NAME_SUFFIX_motor`` per driven joint, a site ``NAME_tip`` at the centre of the tip's end,
and a ``grasp`` keyframe. The hand modules decide which source joints and geoms those are;
this module adds them the same way for every hand.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import mujoco
import numpy as np

#: The driven joints of a holding finger, in the order of its ``joints``.
DRIVEN = ("abd", "mcp", "pip")


class DressedFinger(Protocol):
    """What the keyframe needs of a finger: its name and whether it has a coupled dip."""

    @property
    def name(self) -> str: ...

    @property
    def dip(self) -> str | None: ...


def drive_joint(scene: mujoco.MjSpec, source: str, name: str, force: float) -> None:
    """Rename the joint ``source`` to ``name`` and drive it with a torque motor of range
    ``[-force, force]`` [N m] named ``name + "_motor"``."""
    joint = scene.joint(source)
    joint.name = name
    scene.add_actuator(
        name=f"{name}_motor",
        target=name,
        trntype=mujoco.mjtTrn.mjTRN_JOINT,
        gear=[1.0, 0, 0, 0, 0, 0],
        ctrllimited=True,
        ctrlrange=[-force, force],
    )


def couple_distal(scene: mujoco.MjSpec, source: str, finger: str, ratio: float) -> None:
    """Rename the distal joint ``source`` to ``FINGER_dip`` and tie it to ``FINGER_pip`` by
    a joint equality ``dip = ratio * pip`` (the tendon coupling of a human finger's last two
    joints); the pip's range shrinks to where the coupled dip stays within its own."""
    dip = scene.joint(source)
    dip.name = f"{finger}_dip"
    pip = scene.joint(f"{finger}_pip")
    pip.range = [
        max(pip.range[0], dip.range[0] / ratio),
        min(pip.range[1], dip.range[1] / ratio),
    ]
    scene.add_equality(
        type=mujoco.mjtEq.mjEQ_JOINT,
        name1=dip.name,
        name2=pip.name,
        objtype=mujoco.mjtObj.mjOBJ_JOINT,
        data=[0.0, ratio, 0.0, 0.0, 0.0] + [0.0] * 7,
    )


def add_tip_site(
    distal: mujoco.MjsBody, finger: str, centre: Sequence[float], radius: float
) -> None:
    """The site ``FINGER_tip`` at ``centre`` (the centre of the tip's rounded end, in the
    distal body's frame); its sphere, 1.5 x the tip's ``radius``, is the touch sensor's
    volume: the end's hemisphere and a margin around it."""
    distal.add_site(
        name=f"{finger}_tip",
        type=mujoco.mjtGeom.mjGEOM_SPHERE,
        pos=np.asarray(centre, dtype=float),
        size=[1.5 * radius, 0, 0],
        rgba=[0.9, 0.2, 0.2, 0.3],
        group=4,
    )


def add_grasp_key(
    scene: mujoco.MjSpec,
    fingers: Sequence[DressedFinger],
    grasp: Sequence[tuple[float, float, float]],
    ratio: float,
) -> None:
    """The ``grasp`` keyframe: each finger's (abd, mcp, pip) angles [rad] from ``grasp``,
    its dip at ``ratio`` x pip, the pen 0.2 m above the origin; joints the scene has beside
    them (a hand's undriven ones) at 0."""
    angles = {}
    for finger, values in zip(fingers, grasp, strict=True):
        angles.update({f"{finger.name}_{s}": v for s, v in zip(DRIVEN, values, strict=True)})
        if finger.dip is not None:
            angles[f"{finger.name}_dip"] = ratio * values[2]
    pen = [0.0, 0.0, 0.2, 1.0, 0.0, 0.0, 0.0]
    # qpos in the order of the compiled model's joints (the spec's, depth first)
    qpos = [
        v for j in scene.joints for v in (pen if j.name == "pen" else [angles.get(j.name, 0.0)])
    ]
    scene.add_key(name="grasp", qpos=qpos)

"""A URDF of a pen hand's joint tree, exported from its compiled MuJoCo scene.

Retargeting libraries (dex-retargeting, through pinocchio) read a robot as URDF; the pen
hands exist only as MJCF (``ias4f``, ``ias3f``) or as MJCF built in code (Shadow, LEAP).
:func:`pen_hand_urdf` writes the part of a compiled scene that decides where the fingertips
are: every body on the path from the world to each finger's tip site, with

- one link per body (its mass and principal inertia as the link's ``<inertial>``) and a
  fixed joint for a body without joints (the hand's mount, the palm, ...);
- one ``revolute`` (MuJoCo hinge) or ``prismatic`` (slide) joint per MuJoCo joint, named
  as in the scene, with its axis, its anchor as the origin and its range as the limits
  (effort: the motor's torque range; velocity: :data:`VELOCITY_LIMIT`, which MuJoCo does
  not model). A body with several joints (abd and mcp of the IAS fingers) becomes a chain
  of links ``BODY__JOINT`` in MuJoCo's order, each joint's axis in the frame the previous
  ones turned. A joint's reference angle (MuJoCo's ``qpos0``) is folded into its origin,
  so the URDF's angle is MuJoCo's ``qpos`` itself;
- a distal joint that no motor drives but a joint equality ties to a driven one
  (``dip = ratio * pip`` on the Shadow and LEAP hands, ``PenHandPhysics.coupled``) as a
  revolute joint with ``<mimic joint=LEADER multiplier=ratio offset=.../>``: pinocchio
  loads it as a joint of its own, and dex-retargeting's ``MimicJointKinematicAdaptor``
  (read from those tags) sets it from its leader and folds its Jacobian column into the
  leader's, so the optimiser solves the driven joints only;
- each finger's tip site as a fixed child link ``<finger>_tip`` (the tip sphere's centre,
  where :meth:`PenHandPhysics.tip_positions` is).

The root link ``world`` is MuJoCo's world frame (z up, not the paper frame); positions in
metres, angles in radians. Names are made URDF-safe (``shadow/robot0:palm`` ->
``shadow_robot0_palm``). A joint on the path that is neither driven nor coupled, a ball or
free joint, or a mocap body is refused (no pen hand has one).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

import mujoco
import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ias_gym.sim.pen_hand import PenHandPhysics

__all__ = ["VELOCITY_LIMIT", "HandURDF", "pen_hand_urdf"]

FloatArray = NDArray[np.float64]

#: The URDF's joint velocity limit [rad/s, m/s]: MuJoCo's models have none; URDF needs one.
VELOCITY_LIMIT = 100.0
#: The limits written for a joint MuJoCo does not limit [rad, m].
_UNLIMITED = {"revolute": 2.0 * np.pi, "prismatic": 1.0}


@dataclass(frozen=True)
class HandURDF:
    """A pen hand's URDF and what its user needs to address it.

    Attributes:
        text: the URDF document.
        joints: the driven joints' names, in the hand's order (``PenHandPhysics``'s
            ``hand_qpos_ids``: f1 abd, mcp, pip, f2 ...).
        tips: the tip links' names, one per finger in the hand's order (``f1_tip``, ...).
        mimic: ``(follower, leader, multiplier, offset)`` per coupled joint.
    """

    text: str
    joints: tuple[str, ...]
    tips: tuple[str, ...]
    mimic: tuple[tuple[str, str, float, float], ...]

    def write(self, path: str | Path) -> Path:
        """Write :attr:`text` to ``path`` (UTF-8) and return the path."""
        out = Path(path)
        out.write_text(self.text, encoding="utf-8")
        return out


def _name(raw: str) -> str:
    """A URDF-safe name: every character but letters, digits, ``_`` and ``-`` -> ``_``."""
    return re.sub(r"[^A-Za-z0-9_\-]", "_", raw)


def _num(x: float) -> str:
    """A float that reads back to the same double (``repr``; ``-0.0`` as ``0.0``)."""
    return repr(float(x) + 0.0)


def _origin(pos: FloatArray, rot: FloatArray) -> str:
    """``<origin xyz rpy/>`` of a transform (URDF's rpy: ``R = Rz(y) Ry(p) Rx(r)``)."""
    xyz = " ".join(_num(v) for v in pos)
    return f'<origin xyz="{xyz}" rpy="{" ".join(_num(v) for v in _rpy(rot))}"/>'


def _rpy(rot: FloatArray) -> tuple[float, float, float]:
    """URDF's roll, pitch, yaw [rad] of a rotation matrix, ``R = Rz(y) Ry(p) Rx(r)``.

    The roll is solved last from what pitch and yaw leave, so that near a pitch of +-90
    degrees (the LEAP hand has such frames), where yaw and roll turn about nearly one axis,
    an error in the yaw is taken up by the roll; at +-90 degrees exactly the yaw is 0.
    """
    cos_pitch = math.hypot(rot[0, 0], rot[1, 0])
    pitch = math.atan2(-rot[2, 0], cos_pitch)
    yaw = math.atan2(rot[1, 0], rot[0, 0]) if cos_pitch > 1e-12 else 0.0
    cy, sy, cp, sp = math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch)
    rz_ry = np.array([[cy * cp, -sy, cy * sp], [sy * cp, cy, sy * sp], [-sp, 0.0, cp]])
    rest = rz_ry.T @ rot  # Rx(roll)
    return math.atan2(rest[2, 1], rest[1, 1]), pitch, yaw


def _quat_matrix(quat: FloatArray) -> FloatArray:
    """MuJoCo's unit quaternion (w, x, y, z) as a rotation matrix."""
    out = np.zeros(9)
    mujoco.mju_quat2Mat(out, np.asarray(quat, dtype=float))
    return out.reshape(3, 3)


def _axis_angle(axis: FloatArray, angle: float) -> FloatArray:
    """The rotation by ``angle`` [rad] about the unit ``axis``."""
    if angle == 0.0:
        return np.eye(3)
    return Rotation.from_rotvec(np.asarray(axis, dtype=float) * angle).as_matrix()


class _Writer:
    """Collects links and joints, each once, in the order they are added."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.links: set[str] = set()

    def link(self, name: str, inertial: str = "") -> None:
        if name in self.links:
            raise ValueError(f"two URDF links named {name!r}; rename the bodies")
        self.links.add(name)
        self.lines.append(f"  <link name={quoteattr(name)}>{inertial}</link>")

    def joint(self, name: str, kind: str, parent: str, child: str, origin: str, extra: str) -> None:
        self.lines.append(
            f"  <joint name={quoteattr(name)} type={quoteattr(kind)}>"
            f"<parent link={quoteattr(parent)}/><child link={quoteattr(child)}/>"
            f"{origin}{extra}</joint>"
        )


def _inertial(model: mujoco.MjModel, body: int) -> str:
    """A body's ``<inertial>`` (empty without mass): MuJoCo's principal frame and moments."""
    mass = float(model.body_mass[body])
    if mass <= 0.0:
        return ""
    moments = model.body_inertia[body]
    return (
        f"<inertial>{_origin(model.body_ipos[body], _quat_matrix(model.body_iquat[body]))}"
        f'<mass value="{_num(mass)}"/><inertia ixx="{_num(moments[0])}" ixy="0.0" '
        f'ixz="0.0" iyy="{_num(moments[1])}" iyz="0.0" izz="{_num(moments[2])}"/></inertial>'
    )


def pen_hand_urdf(physics: PenHandPhysics, name: str = "pen_hand") -> HandURDF:
    """The URDF of a pen hand's joint tree (the module's docstring says what it holds).

    Args:
        physics: the compiled scene with its hand's names looked up.
        name: the ``<robot>``'s name.

    Returns:
        The URDF, its driven joints and tip links.

    Raises:
        ValueError: a joint on a tip's path that is neither driven nor coupled to a driven
            joint, a ball or free joint, a mocap body, or two bodies whose safe names clash.
    """
    model = physics.model
    obj = mujoco.mjtObj
    driven = [int(model.dof_jntid[d]) for d in physics.hand_dof_ids]
    mimic: dict[int, tuple[int, float]] = {
        int(model.dof_jntid[dof]): (driven[leader], ratio) for dof, leader, ratio in physics.coupled
    }
    effort: dict[int, float] = {}
    for a in range(model.nu):
        if int(model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT):
            limit = float(np.max(np.abs(model.actuator_ctrlrange[a])))
            effort[int(model.actuator_trnid[a, 0])] = limit * abs(float(model.actuator_gear[a, 0]))

    def joint_name(j: int) -> str:
        return _name(mujoco.mj_id2name(model, obj.mjOBJ_JOINT, j) or f"joint{j}")

    def body_name(b: int) -> str:
        return "world" if b == 0 else _name(mujoco.mj_id2name(model, obj.mjOBJ_BODY, b) or f"b{b}")

    # every body on a path from the world to a tip site, parents first
    wanted: set[int] = set()
    for site in physics.tip_site_ids:
        b = int(model.site_bodyid[site])
        while b != 0:
            wanted.add(b)
            b = int(model.body_parentid[b])
    out = _Writer()
    out.link("world")
    mimic_rows: list[tuple[str, str, float, float]] = []
    for body in sorted(wanted):  # MuJoCo numbers a parent before its children
        if int(model.body_mocapid[body]) >= 0:
            raise ValueError(f"body {body_name(body)!r} is a mocap body; URDF has none")
        parent = body_name(int(model.body_parentid[body]))
        # the transform still to apply before the next joint (or the body's own frame)
        pos = model.body_pos[body].astype(float)
        rot = _quat_matrix(model.body_quat[body])
        joints = range(model.body_jntadr[body], model.body_jntadr[body] + model.body_jntnum[body])
        for j in joints:
            jtype = int(model.jnt_type[j])
            if jtype == int(mujoco.mjtJoint.mjJNT_HINGE):
                kind = "revolute"
            elif jtype == int(mujoco.mjtJoint.mjJNT_SLIDE):
                kind = "prismatic"
            else:
                raise ValueError(f"joint {joint_name(j)!r}: only hinges and slides export")
            if j not in driven and j not in mimic:
                raise ValueError(
                    f"joint {joint_name(j)!r} is on a fingertip's path but neither driven "
                    "nor coupled to a driven joint"
                )
            axis = model.jnt_axis[j].astype(float)
            anchor = model.jnt_pos[j].astype(float)
            q0 = float(model.qpos0[model.jnt_qposadr[j]])
            # MuJoCo: X = X_prev T(p) R(a, q - q0) T(-p); URDF: origin T(p) R(a, -q0), then
            # R(a, q) about the axis, and T(-p) left for what follows
            if kind == "revolute":
                pos, rot = pos + rot @ anchor, rot @ _axis_angle(axis, -q0)
            else:  # a slide moves along its axis by q - q0 wherever its anchor is
                pos, anchor = pos - rot @ (q0 * axis), np.zeros(3)
            last = j == joints[-1] and not np.any(anchor)
            child = body_name(body) if last else f"{body_name(body)}__{joint_name(j)}"
            out.link(child, _inertial(model, body) if last else "")
            if bool(model.jnt_limited[j]):
                lower, upper = (float(v) for v in model.jnt_range[j])
            else:
                lower, upper = -_UNLIMITED[kind], _UNLIMITED[kind]
            extra = (
                f'<axis xyz="{" ".join(_num(v) for v in axis)}"/>'
                f'<limit lower="{_num(lower)}" upper="{_num(upper)}" '
                f'effort="{_num(effort.get(j, 0.0))}" velocity="{_num(VELOCITY_LIMIT)}"/>'
            )
            if j in mimic:
                leader, ratio = mimic[j]
                q0_leader = float(model.qpos0[model.jnt_qposadr[leader]])
                offset = q0 - ratio * q0_leader  # MuJoCo ties q - q0 to ratio (q_l - q0_l)
                extra += (
                    f"<mimic joint={quoteattr(joint_name(leader))} "
                    f'multiplier="{_num(ratio)}" offset="{_num(offset)}"/>'
                )
                mimic_rows.append((joint_name(j), joint_name(leader), ratio, offset))
            out.joint(joint_name(j), kind, parent, child, _origin(pos, rot), extra)
            parent, pos, rot = child, -anchor, np.eye(3)
        if parent != body_name(body):  # no joint, or the last joint's anchor off the origin
            out.link(body_name(body), _inertial(model, body))
            out.joint(
                f"{body_name(body)}__fixed", "fixed", parent, body_name(body), _origin(pos, rot), ""
            )
    tips = []
    for finger, site in zip(physics.fingers, physics.tip_site_ids, strict=True):
        tip = f"{_name(finger)}_tip"
        out.link(tip)
        origin = _origin(model.site_pos[site], _quat_matrix(model.site_quat[site]))
        out.joint(
            f"{tip}__fixed", "fixed", body_name(int(model.site_bodyid[site])), tip, origin, ""
        )
        tips.append(tip)
    text = (
        '<?xml version="1.0"?>\n'
        f"<!-- exported from the MuJoCo scene by ias_gym.sim.urdf_export -->\n"
        f"<robot name={quoteattr(name)}>\n" + "\n".join(out.lines) + "\n</robot>\n"
    )
    return HandURDF(
        text=text,
        joints=tuple(joint_name(j) for j in driven),
        tips=tuple(tips),
        mimic=tuple(mimic_rows),
    )

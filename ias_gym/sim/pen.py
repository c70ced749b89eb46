"""The pen on a free joint and the paper frame, shared by the pen-hand and glove scenes.

Frames. The paper frame has x = pen axis, y = vertical (up), z = lateral. MuJoCo's world has
z up, so ``paper x = MuJoCo x``, ``paper y = MuJoCo z``, ``paper z = -MuJoCo y``
(a right-handed rotation by +90 degrees about x): ``v_mj = R_PAPER_TO_MJ @ v_paper``.
:class:`FreePenPhysics` answers the pen's questions (pose, twist, mass) in that frame;
positions have their origin at the pen's nominal centre. Units are SI (m, rad, N, N m, kg).
"""

from __future__ import annotations

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ias_gym.errors import (
    NameNotFoundError,
)

FloatArray = NDArray[np.float64]

#: Rotation from the paper frame to MuJoCo's world frame: ``v_mj = R_PAPER_TO_MJ @ v_paper``.
#: Columns are the paper axes in MuJoCo coordinates: x -> x, y -> z, z -> -y.
R_PAPER_TO_MJ: FloatArray = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
R_PAPER_TO_MJ.flags.writeable = False


def mj_to_paper(v: ArrayLike) -> FloatArray:
    """Vectors (``(..., 3)``) from MuJoCo's world frame to the paper frame (direction only)."""
    return np.asarray(v, dtype=float) @ R_PAPER_TO_MJ


def paper_to_mj(v: ArrayLike) -> FloatArray:
    """Vectors (``(..., 3)``) from the paper frame to MuJoCo's world frame (direction only)."""
    return np.asarray(v, dtype=float) @ R_PAPER_TO_MJ.T


def wrench_mj_to_paper(w: ArrayLike) -> FloatArray:
    """Wrenches ``[f; m]`` (``(..., 6)``, N and N m) from MuJoCo's world frame to the paper's.

    Both halves rotate with ``R_PAPER_TO_MJ``; the reference point is unchanged.
    """
    w = np.asarray(w, dtype=float)
    return (w.reshape(*w.shape[:-1], 2, 3) @ R_PAPER_TO_MJ).reshape(w.shape)


def wrench_paper_to_mj(w: ArrayLike) -> FloatArray:
    """Wrenches ``[f; m]`` (``(..., 6)``) from the paper frame to MuJoCo's world frame."""
    w = np.asarray(w, dtype=float)
    return (w.reshape(*w.shape[:-1], 2, 3) @ R_PAPER_TO_MJ.T).reshape(w.shape)


def rpy_to_matrix(rpy: ArrayLike) -> FloatArray:
    """Rotation matrix of roll-pitch-yaw angles [rad], eq. (25).

    Convention (ours; the paper does not fix it): fixed axes x, y, z, i.e.
    ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``, roll about the pen axis (paper x), pitch about the
    vertical (paper y), yaw about the lateral axis (paper z). The pen's axis ``R e_x`` does not
    depend on roll, and the see-saw tilt of sec. 4.3 ("rotate about z") is the yaw angle.
    """
    r, p, y = np.asarray(rpy, dtype=float)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def matrix_to_rpy(rot: ArrayLike) -> FloatArray:
    """Roll-pitch-yaw angles [rad] of a rotation matrix; inverse of :func:`rpy_to_matrix`.

    Pitch is in [-pi/2, pi/2]; roll and yaw in (-pi, pi].
    """
    m = np.asarray(rot, dtype=float)
    return np.array(
        [
            np.arctan2(m[2, 1], m[2, 2]),
            np.arctan2(-m[2, 0], np.hypot(m[0, 0], m[1, 0])),
            np.arctan2(m[1, 0], m[0, 0]),
        ]
    )


def lookup(model: mujoco.MjModel, obj: mujoco.mjtObj, name: str) -> int:
    """The id of the ``obj`` named ``name`` in ``model``.

    Raises:
        NameNotFoundError: no such name; the message lists the names that exist.
    """
    idx = mujoco.mj_name2id(model, obj, name)
    if idx < 0:
        kind = obj.name.removeprefix("mjOBJ_").lower()
        count = {
            int(mujoco.mjtObj.mjOBJ_BODY): model.nbody,
            int(mujoco.mjtObj.mjOBJ_JOINT): model.njnt,
            int(mujoco.mjtObj.mjOBJ_GEOM): model.ngeom,
            int(mujoco.mjtObj.mjOBJ_SITE): model.nsite,
            int(mujoco.mjtObj.mjOBJ_SENSOR): model.nsensor,
            int(mujoco.mjtObj.mjOBJ_KEY): model.nkey,
        }[int(obj)]
        names = [n for i in range(count) if (n := mujoco.mj_id2name(model, obj, i))]
        raise NameNotFoundError(
            f"no {kind} named {name!r} in the model. Available {kind} names: {names}"
        )
    return int(idx)


class FreePenPhysics:
    """Named questions about a pen on a free joint: its pose, twist and mass (paper frame).

    The part of a scene's physics that only depends on the pen, shared by the pen-hand
    scene (:class:`~ias_gym.sim.pen_hand.PenHandPhysics`) and the glove scene
    (:class:`~ias_gym.sim.glove_contacts.GlovePenPhysics`). Positions have their origin at
    the pen's nominal centre (its position in the model's ``qpos0``); SI units.

    Args:
        model: compiled scene with a pen body on a free joint, its centre of mass at the
            body origin.
        data: its data.
        pen: name of the pen's body, free joint and geom (a capsule).

    Attributes:
        model, data: as given.
        pen_body_id, pen_geom_id, pen_qpos_adr, pen_dof_adr: the pen's body and geom ids and
            its free joint's addresses (``qpos[adr:adr+7]`` = position, quaternion w-x-y-z;
            ``qvel[adr:adr+6]`` = linear velocity (world), angular velocity (body frame)).
        origin_mj: the nominal pen centre [m] in MuJoCo's world frame (origin of the paper
            frame; the pen body's position in the XML).

    Raises:
        NameNotFoundError: a name is missing; the message lists the names that exist.
        ValueError: the pen's joint is not free, or its centre of mass is off its origin.
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, pen: str = "pen") -> None:
        self.model = model
        self.data = data
        obj = mujoco.mjtObj
        self.pen_body_id = lookup(model, obj.mjOBJ_BODY, pen)
        self.pen_geom_id = lookup(model, obj.mjOBJ_GEOM, pen)
        pen_joint = lookup(model, obj.mjOBJ_JOINT, pen)
        if int(model.jnt_type[pen_joint]) != int(mujoco.mjtJoint.mjJNT_FREE):
            raise ValueError(f"joint {pen!r} must be a free joint")
        # qpos[0:3] of the free joint is then the centre of mass, as r of eq. (25) wants.
        if not np.allclose(model.body_ipos[self.pen_body_id], 0.0, atol=1e-9):
            raise ValueError("the pen's centre of mass must be at its body origin")
        self.pen_qpos_adr = int(model.jnt_qposadr[pen_joint])
        self.pen_dof_adr = int(model.jnt_dofadr[pen_joint])
        #: Nominal pen centre in MuJoCo's world frame [m]: the origin of the paper frame.
        self.origin_mj: FloatArray = model.qpos0[self.pen_qpos_adr : self.pen_qpos_adr + 3].copy()
        # The pen's capsule: half-length of its cylindrical part [m] (for closest-point queries).
        self._pen_half_length = float(model.geom_size[self.pen_geom_id, 1])
        self._pen_rot_mj = np.zeros(9)  # reused by _pen_rot: no allocation per call
        # The model's pen as built: what a controller plans with when a task scales the
        # simulated pen's mass (ias_gym.envs.disturbances).
        self.pen_mass_nominal = float(model.body_mass[self.pen_body_id])
        self._pen_inertia_nominal = model.body_inertia[self.pen_body_id].copy()

    def _pen_rot(self) -> FloatArray:
        """The pen's rotation matrix in MuJoCo's world frame, from ``qpos`` (a reused buffer)."""
        mujoco.mju_quat2Mat(
            self._pen_rot_mj, self.data.qpos[self.pen_qpos_adr + 3 : self.pen_qpos_adr + 7]
        )
        return self._pen_rot_mj.reshape(3, 3)

    def pen_rotation(self) -> FloatArray:
        """Orientation of the pen's frame in the paper frame, ``(3, 3)`` (identity at rest)."""
        return R_PAPER_TO_MJ.T @ self._pen_rot() @ R_PAPER_TO_MJ

    def pen_pose(self) -> tuple[FloatArray, FloatArray]:
        """The pen's pose as in eq. (25): ``(r, phi)``.

        Returns:
            r: centre-of-mass position [m], paper frame, relative to the nominal pen centre.
            phi: roll, pitch, yaw [rad] of the pen in the paper frame, fixed axes x-y-z
                (``R = Rz(yaw) Ry(pitch) Rx(roll)``, see :func:`rpy_to_matrix`): roll about
                the pen axis, the see-saw tilt of sec. 4.3 is yaw.
        """
        pos = mj_to_paper(
            self.data.qpos[self.pen_qpos_adr : self.pen_qpos_adr + 3] - self.origin_mj
        )
        return pos, matrix_to_rpy(self.pen_rotation())

    def pen_twist(self) -> tuple[FloatArray, FloatArray]:
        """The pen's twist ``(v, omega)`` of eq. (15), paper frame.

        Returns:
            v: centre-of-mass velocity [m/s].
            omega: angular velocity [rad/s] in the (world-aligned) paper frame. MuJoCo keeps a
                free joint's angular velocity ``qvel[3:6]`` in the body frame; it is rotated here.
        """
        qv = self.data.qvel[self.pen_dof_adr : self.pen_dof_adr + 6]
        return mj_to_paper(qv[:3]), mj_to_paper(self._pen_rot() @ qv[3:])

    def pen_com(self) -> FloatArray:
        """Pen centre of mass [m], paper frame (from the last forward pass)."""
        return mj_to_paper(self.data.xipos[self.pen_body_id] - self.origin_mj)

    def pen_mass(self) -> float:
        """Pen mass m [kg] of eq. (33)."""
        return float(self.model.body_mass[self.pen_body_id])

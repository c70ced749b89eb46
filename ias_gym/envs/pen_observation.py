"""What every pen task observes of the hand and the pen, and how one step reads it.

:func:`pen_observation_parts` names the parts every pen task's observation begins with;
:class:`PenStateReader` reads a step's measurements (:class:`~ias_gym.envs.pen_hand_types.PenState`)
from MuJoCo's arrays and sensors in one pass, through views into MjData's buffers made once,
because ``env.step`` should cost little more than the simulation it runs
(``bench/bench_envs.py``). Used by :class:`~ias_gym.envs.pen_hand_env.PenHandEnv`; paper
frame, SI units.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from ias_gym.envs.layout import ObservationParts
from ias_gym.envs.pen_hand_types import PenState
from ias_gym.sim.pen_hand import PenHandPhysics

#: MuJoCo world -> paper frame: paper (x, y, z) = MuJoCo (x, z, -y).
TO_PAPER_INDEX = np.array([0, 2, 1])  # and negate the last


def pen_observation_parts(n_joints: int, n_fingers: int) -> ObservationParts:
    """The parts every pen task's observation begins with, in order (paper frame, SI).

    Args:
        n_joints: the hand's joints (3 per finger).
        n_fingers: its fingers.
    """
    return (
        ("joint_angles", n_joints),  # hand joint angles [rad], the hand's joint order
        ("joint_velocities", n_joints),  # [rad/s]
        ("pen_position", 3),  # pen centre relative to its nominal position [m]
        ("pen_axis", 3),  # unit vector along the pen's axis (its roll is free)
        ("pen_velocity", 3),  # [m/s]
        ("pen_omega", 3),  # angular velocity [rad/s]
        ("tip_forces", 3 * n_fingers),  # net force of each fingertip on the pen [N], 3 each
        ("time_fraction", 1),  # time since reset / episode duration [-]
    )


def as_index(ids: NDArray[np.integer[Any]]) -> slice | NDArray[np.integer[Any]]:
    """``ids`` as a slice when they are consecutive (indexing then gives a view)."""
    if len(ids) and np.array_equal(ids, np.arange(ids[0], ids[0] + len(ids))):
        return slice(int(ids[0]), int(ids[0]) + len(ids))
    return ids


class PenStateReader:
    """Reads a pen-hand scene's :class:`~ias_gym.envs.pen_hand_types.PenState` in one pass.

    The pen's and hand's state come from ``qpos``/``qvel`` (now); fingertip positions and
    contact sensors (``fN_pen_force``: number of contacts, net force of the tip on the pen,
    world frame) from the last forward pass.

    Args:
        model, data: the compiled pen-hand scene and its data (the views are into ``data``).
        physics: its :class:`~ias_gym.sim.pen_hand.PenHandPhysics`.
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, physics: PenHandPhysics) -> None:
        self.physics = physics
        k = physics.n_fingers
        # fN_pen_force sensors: number of contacts, net force of the tip on the pen (world).
        adr = np.array([model.sensor(f"{f}_pen_force").adr[0] for f in physics.fingers])
        # Views into MjData's fixed buffers, made once: each attribute access of the
        # bindings builds a new array (about 0.3 us, several per step).
        pen_q, pen_v = physics.pen_qpos_adr, physics.pen_dof_adr
        self._qpos, self._qvel = data.qpos, data.qvel
        self._site_xpos = data.site_xpos
        self._pen_xpos = data.xpos[physics.pen_body_id]
        self._pen_pos = data.qpos[pen_q : pen_q + 3]
        self._pen_quat = data.qpos[pen_q + 3 : pen_q + 7]
        self._pen_lin = data.qvel[pen_v : pen_v + 3]
        self._pen_ang = data.qvel[pen_v + 3 : pen_v + 6]
        self._origin = physics.origin_mj
        self._tip_ids = np.asarray(physics.tip_site_ids)
        # Scratch for the pen's rotation (its axis: column 0, a view), its centre relative to
        # nominal and its angular velocity in the world frame.
        self._rot = np.zeros(9)
        self._rot_matrix = self._rot.reshape(3, 3)
        self._axis = self._rot[0::3]
        self._position = np.zeros(3)
        self._omega = np.zeros(3)
        # The force sensors (count, fx, fy, fz each): one view when they sit back to back
        # (the counts a strided view of it), else gathered by address every read.
        self._sensordata = data.sensordata
        self._found_adr = adr
        self._force_adr = (adr[:, None] + np.arange(1, 4)).ravel()
        self._forces: NDArray[np.float64] | None = None
        self._found: NDArray[np.float64] | None = None
        if np.all(np.diff(adr) == 4):
            self._forces = data.sensordata[adr[0] : adr[0] + 4 * k]
            self._found = self._forces[0::4]
            force_at = 4 * np.arange(k)[:, None] + np.arange(1, 4)  # in the view
        else:
            force_at = 3 * np.arange(k)[:, None] + np.arange(3)  # in the gathered forces
        # One gather and one sign flip make the observed block from qpos, qvel and the pen's
        # MuJoCo-frame rows (position, axis, velocity, angular velocity, then the forces'
        # source): the hand's joint angles and velocities, then the pen's rows in the paper
        # frame: paper (x, y, z) = MuJoCo (x, z, -y) (TO_PAPER_INDEX, then negate the last).
        nq, nv = model.nq, model.nv
        rows = nq + nv + np.vstack([np.arange(12).reshape(4, 3), 12 + force_at])
        self._gather = np.concatenate(
            [physics.hand_qpos_ids, nq + physics.hand_dof_ids, rows[:, TO_PAPER_INDEX].ravel()]
        )
        self._n_joint_values = 2 * physics.n_hand_dofs
        self._sign = np.concatenate(
            [np.ones(self._n_joint_values), np.tile([1.0, 1.0, -1.0], 4 + k)]
        )

    def read(self) -> PenState:
        """This step's measurements (one pass over MuJoCo's arrays)."""
        mujoco.mju_quat2Mat(self._rot, self._pen_quat)
        np.subtract(self._pen_pos, self._origin, out=self._position)
        np.dot(self._rot_matrix, self._pen_ang, out=self._omega)  # body -> world
        forces, found = self._forces, self._found
        if forces is None or found is None:
            forces = self._sensordata[self._force_adr]
            found = self._sensordata[self._found_adr]
        mj = np.concatenate(
            (self._qpos, self._qvel, self._position, self._axis, self._pen_lin, self._omega, forces)
        )
        observed = mj[self._gather]
        observed *= self._sign  # (x 1.0 leaves a value as it is, bit for bit)
        n = self._n_joint_values
        # (take: the rows as fancy indexing gives them, in a third of its time)
        tips = self._site_xpos.take(self._tip_ids, axis=0) - self._pen_xpos
        return PenState(observed[n:], found > 0.0, tips @ self._axis, joints=observed[:n])

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
        # fN_pen_force sensors: number of contacts, net force of the tip on the pen (world).
        adr = np.array([model.sensor(f"{f}_pen_force").adr[0] for f in physics.fingers])
        self._found_adr = adr
        self._force_adr = (adr[:, None] + np.arange(1, 4)).ravel()
        self._rot = np.zeros(9)
        self._rows = np.zeros((4 + physics.n_fingers, 3))
        # Views into MjData's fixed buffers, made once: each attribute access of the
        # bindings builds a new array (about 0.3 us, several per step).
        pen_q, pen_v = physics.pen_qpos_adr, physics.pen_dof_adr
        self._sensordata, self._site_xpos = data.sensordata, data.site_xpos
        self._pen_xpos = data.xpos[physics.pen_body_id]
        self._pen_pos = data.qpos[pen_q : pen_q + 3]
        self._pen_quat = data.qpos[pen_q + 3 : pen_q + 7]
        self._pen_lin = data.qvel[pen_v : pen_v + 3]
        self._pen_ang = data.qvel[pen_v + 3 : pen_v + 6]
        self._axis = self._rot[0::3]  # the pen's axis: column 0 of the rotation, a view
        self._tip_ix = as_index(physics.tip_site_ids)
        # The force sensors as views when they sit back to back (count, fx, fy, fz each).
        self._sensor_block: NDArray[np.float64] | None = None
        if np.all(np.diff(adr) == 4):
            block = data.sensordata[adr[0] : adr[0] + 4 * len(adr)].reshape(len(adr), 4)
            self._sensor_block = block

    def read(self) -> PenState:
        """This step's measurements (one pass over MuJoCo's arrays)."""
        mujoco.mju_quat2Mat(self._rot, self._pen_quat)
        rot = self._rot.reshape(3, 3)
        rows = self._rows  # (4 + k, 3) in MuJoCo's frame
        np.subtract(self._pen_pos, self.physics.origin_mj, out=rows[0])
        rows[1] = self._axis
        rows[2] = self._pen_lin
        np.dot(rot, self._pen_ang, out=rows[3])  # body -> world
        block = self._sensor_block
        if block is not None:
            rows[4:] = block[:, 1:]
            found = block[:, 0]
        else:
            rows[4:] = self._sensordata[self._force_adr].reshape(-1, 3)
            found = self._sensordata[self._found_adr]
        paper = rows[:, TO_PAPER_INDEX]
        paper[:, 2] *= -1.0
        tips = self._site_xpos[self._tip_ix] - self._pen_xpos
        return PenState(paper.ravel(), found > 0, tips @ self._axis)

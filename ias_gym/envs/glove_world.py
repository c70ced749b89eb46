"""The glove world: the person's hand with the pen, its observation and the force display.

:class:`GloveWorldEnv` is the base of :class:`~ias_gym.envs.glove_grasp.GloveGraspEnv` (not
registered itself). It compiles the scene of one person's hand
(:func:`~ias_gym.sim.glove_scene.load_glove_scene`), looks up the hand's joints and motors,
the thumb's coupled hinges, the glove's actuated joints and the pen once, puts the hand at
joint angles, turns one pass over the pen's contacts
(:meth:`~ias_gym.sim.glove_contacts.GlovePenPhysics.contact_pass`) into the force display
``tau = J^T f`` on the glove's actuated joints, assembles the observation
(:data:`OBSERVATION_PARTS`, by name :data:`OBSERVATION`) and renders the scene. The glove,
the task (reward, success, episode end) and the episode's loop are ``GloveGraspEnv``'s.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from numpy.typing import NDArray

from ias_gym.envs.layout import ObservationParts, layout_size, observation_layout
from ias_gym.glove.device import ACTUATED_JOINTS
from ias_gym.glove.hand import JOINT_NAMES, PersonParams
from ias_gym.sim.glove_contacts import GlovePenPhysics, PenContactPass
from ias_gym.sim.glove_scene import (
    FINGER_ABOVE,
    FINGER_GEOMS,
    FINGER_TIPS,
    SUPPORT_GEOMS,
    THUMB_DRIVER,
    load_glove_scene,
    thumb_coupling,
)

FloatArray = NDArray[np.float64]

#: The glove world's observation, in order: each part's name and size. :data:`OBSERVATION`
#: maps the names to their slices; consumers index by name, never by column number.
OBSERVATION_PARTS: ObservationParts = (
    ("joint_angles", len(JOINT_NAMES)),  # hand joint angles [rad], JOINT_NAMES order
    ("joint_velocities", len(JOINT_NAMES)),  # [rad/s]
    ("pen_position", 3),  # pen centre relative to its start, world frame [m]
    ("pen_quat", 4),  # pen orientation quaternion (w, x, y, z), world frame
    ("pen_velocity", 3),  # [m/s], world frame
    ("pen_omega", 3),  # [rad/s], world frame
    ("feedback_torques", len(ACTUATED_JOINTS)),  # force display on ACTUATED_JOINTS [N m]
    ("time", 1),  # episode time [s]
)


#: Names to slices of the glove world's observation (:data:`OBSERVATION_PARTS`).
OBSERVATION: dict[str, slice] = observation_layout(OBSERVATION_PARTS)
#: Size of the glove world's observation.
OBSERVATION_SIZE = layout_size(OBSERVATION_PARTS)


class GloveWorldEnv(gym.Env[FloatArray, NDArray[np.float32]]):
    """The scene of a person's hand holding the pen, stepped ``frame_skip`` physics steps at
    a time (base of :class:`~ias_gym.envs.glove_grasp.GloveGraspEnv`).

    Args:
        person: the hand's owner (the scene is built for their hand).
        control_dt: one env step [s]; a multiple of the physics step.

    Raises:
        ValueError: ``control_dt`` is not a multiple of the physics step.

    Attributes:
        model, data: the compiled scene of the person's hand and its state.
        physics: :class:`~ias_gym.sim.glove_contacts.GlovePenPhysics` of the scene (index,
            thumb).
        contact_pass: the pen's contacts of the last :meth:`_force_display` (``None``
            before).
    """

    # The episode's state the observation shows (the env's reset and step set it).
    _steps: int  # control steps since reset
    _pen_start: FloatArray  # the pen's position at reset [m]
    _feedback: FloatArray  # the force display on ACTUATED_JOINTS [N m]

    def __init__(self, person: PersonParams, control_dt: float) -> None:
        m = self.model = load_glove_scene(person)
        self.data = mujoco.MjData(m)
        self.frame_skip = round(control_dt / m.opt.timestep)
        if self.frame_skip < 1 or not math.isclose(self.frame_skip * m.opt.timestep, control_dt):
            raise ValueError(f"control_dt must be a multiple of {m.opt.timestep} s")

        # Names looked up once (STYLE.md).
        joints = [m.joint(n).id for n in JOINT_NAMES]
        self._qadr = m.jnt_qposadr[joints].copy()
        self._vadr = m.jnt_dofadr[joints].copy()
        self._act = np.array([m.actuator(n).id for n in JOINT_NAMES])
        self._ctrl_lo = m.actuator_ctrlrange[self._act, 0].copy()
        self._ctrl_hi = m.actuator_ctrlrange[self._act, 1].copy()
        # The thumb's passive hinges follow thumb_flexion by the model's equalities.
        coupled, self._coupling = thumb_coupling(m)
        self._coupled_q = m.jnt_qposadr[coupled].copy()
        self._coupled_dofs = m.jnt_dofadr[coupled].copy()
        self._flex = JOINT_NAMES.index(THUMB_DRIVER)
        self._fb_dofs = np.array([m.jnt_dofadr[m.joint(n).id] for n in ACTUATED_JOINTS])
        self._fb_flex = ACTUATED_JOINTS.index(THUMB_DRIVER)
        self._pen_body = m.body("pen").id
        self._pen_v = m.jnt_dofadr[m.joint("pen").id]
        self._rest_geoms = frozenset(m.geom(n).id for n in SUPPORT_GEOMS)
        # The pen and the fingers' contacts: one pass per step feeds the force display and
        # (through contact_pass) the skill model's W and c.
        self.physics = GlovePenPhysics(m, self.data, FINGER_GEOMS, FINGER_TIPS, FINGER_ABOVE)
        self.contact_pass: PenContactPass | None = None  # of the last reset or step
        self._warnings = self.data.warning.number  # a view: MuJoCo's warning counters
        self._renderer: Any = None
        self._control_dt = control_dt
        self._steps = 0
        self._pen_start = np.zeros(3)
        self._feedback = np.zeros(len(ACTUATED_JOINTS))

    @property
    def dt(self) -> float:
        """Control period [s]: one ``step`` = one glove read (``frame_skip`` physics steps),
        as Gymnasium's MuJoCo envs have it."""
        return float(self.model.opt.timestep * self.frame_skip)

    def _place_hand(self, theta: FloatArray) -> None:
        """Reset MuJoCo's state: hand at ``theta`` [rad] and at rest, pen at its start."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[self._qadr] = theta
        d.qpos[self._coupled_q] = self._coupling * theta[self._flex]
        d.ctrl[self._act] = theta
        mujoco.mj_forward(m, d)

    def _force_display(self) -> tuple[FloatArray, tuple[bool, bool], float, bool]:
        """(tau on ACTUATED_JOINTS [N m], (index, thumb) touch, pinch normal force [N],
        pen touches the support or floor), from one pass over the contacts (kept in
        :attr:`contact_pass`)."""
        cp = self.contact_pass = self.physics.contact_pass()
        tau = cp.qfrc[self._fb_dofs]  # a copy (fancy indexing)
        # thumb_flexion drives the coupled MCP-share and IP hinges: virtual work.
        tau[self._fb_flex] += float(self._coupling @ cp.qfrc[self._coupled_dofs])
        touch = (bool(cp.count[0]), bool(cp.count[1]))
        rest = not self._rest_geoms.isdisjoint(cp.other_geoms)
        return tau, touch, float(np.add.reduce(cp.normal_force)), rest

    def _observation(self) -> FloatArray:
        """The observation now (:data:`OBSERVATION_PARTS`)."""
        d = self.data
        pen_v = d.qvel[self._pen_v : self._pen_v + 6]
        # Free joint: linear velocity in world, angular velocity in the body frame -> world.
        omega = d.xmat[self._pen_body].reshape(3, 3) @ pen_v[3:6]
        return np.concatenate(
            [
                d.qpos[self._qadr],
                d.qvel[self._vadr],
                d.xpos[self._pen_body] - self._pen_start,
                d.xquat[self._pen_body],
                pen_v[0:3],
                omega,
                self._feedback,
                [self._steps * self._control_dt],
            ]
        )

    def render(self) -> NDArray[np.uint8] | None:
        """The scene from the ``perspective`` camera as ``(360, 480, 3)`` RGB, or ``None``
        without ``render_mode="rgb_array"``."""
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            self._renderer = mujoco.Renderer(self.model, 360, 480)
        self._renderer.update_scene(self.data, camera="perspective")
        return np.asarray(self._renderer.render())

    def close(self) -> None:
        """Release the renderer."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

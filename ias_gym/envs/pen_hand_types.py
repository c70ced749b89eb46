"""The pen tasks' value types: their configuration (:class:`PenHandConfig`), what the task
wants of the pen at one instant (:class:`PenReference`) and the measurements one step uses
(:class:`PenState`); paper frame, SI units. Split out of :mod:`ias_gym.envs.pen_hand_env`,
which re-exports them.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import NDArray

from ias_gym.envs.disturbances import DisturbanceSettings
from ias_gym.sim.hands import DEFAULT_HAND, get_hand

FloatArray = NDArray[np.float64]


@dataclasses.dataclass(frozen=True)
class PenReference:
    """What the task wants of the pen and the fingers at one instant (paper frame, SI).

    The desired object trajectory of eqs. (25)-(28) with its derivatives; the pen's roll
    about its own axis is free, so the orientation is given by the axis direction.

    Attributes:
        position, velocity, acceleration: pen centre r_d [m], its derivatives.
        axis: unit direction of the pen's axis.
        omega, alpha: angular velocity [rad/s] and acceleration [rad/s^2].
        sliding: {finger index: unit sliding direction in (t_x, t_z)} (docs/NOTES.md, eq. 20).
        contact_x: scheduled contact positions along the pen [m], ``None``: hold them.
        contact_vx: their rates [m/s].
    """

    position: FloatArray
    velocity: FloatArray
    acceleration: FloatArray
    axis: FloatArray
    omega: FloatArray
    alpha: FloatArray
    sliding: dict[int, FloatArray]
    contact_x: FloatArray | None = None
    contact_vx: FloatArray | None = None


class PenState:
    """The measurements one env step uses (paper frame, SI units).

    Attributes:
        vector: ``(12 + 3k,)`` the observation block (k fingers): pen position relative to
            its nominal centre [m] (3), unit axis (3), velocity [m/s] (3), angular velocity
            [rad/s] (3), net force of each fingertip on the pen [N] (k x 3).
        touching: ``(k,)`` bool, fingertip touches the pen.
        tip_x: ``(k,)`` each fingertip's position along the pen's axis from its centre [m].
        joints: ``(2n,)`` the hand's n joint angles [rad], then their velocities [rad/s], in
            the hand's joint order (the observation's first parts).
        position_error: ``|position|`` [m].
        tilt: angle between the pen's axis and its nominal direction (paper x) [rad].
    """

    __slots__ = ("joints", "position_error", "tilt", "tip_x", "touching", "vector")

    def __init__(
        self,
        vector: FloatArray,
        touching: NDArray[np.bool_],
        tip_x: FloatArray,
        joints: FloatArray,
    ) -> None:
        self.vector = vector
        self.touching = touching
        self.tip_x = tip_x
        self.joints = joints
        x, y, z, ax = vector[:4].tolist()
        self.position_error = math.sqrt(x * x + y * y + z * z)
        self.tilt = math.acos(min(1.0, abs(ax)))

    @property
    def position(self) -> FloatArray:
        """Pen centre relative to its nominal position [m]."""
        return self.vector[0:3]

    @property
    def axis(self) -> FloatArray:
        """Unit vector along the pen's axis (independent of its roll)."""
        return self.vector[3:6]

    @property
    def velocity(self) -> FloatArray:
        """Pen centre velocity [m/s]."""
        return self.vector[6:9]

    @property
    def omega(self) -> FloatArray:
        """Pen angular velocity [rad/s]."""
        return self.vector[9:12]

    @property
    def tip_force(self) -> FloatArray:
        """``(k, 3)`` net force of each fingertip on the pen [N]."""
        return self.vector[12:].reshape(-1, 3)


@dataclasses.dataclass(frozen=True)
class PenHandConfig:
    """Settings shared by the pen tasks (units in the comments)."""

    control_dt: float = 0.01  # one env step [s]; a multiple of the physics step (1 or 2 ms)
    duration: float = 4.0  # episode length [s] (the registered max_episode_steps matches)
    min_grasp_force: float = 0.2  # minimum normal force a controller should keep [N]
    pen_position_noise: float = 0.001  # reset: uniform +- per axis [m]
    contact_noise: float = 0.001  # reset: uniform +- per contact along the pen [m]
    penetration: float = 3e-4  # reset: tip-pen overlap [m]
    drop_distance: float = 0.02  # pen centre this far from nominal = dropped [m]
    max_contact_gap: float = 0.02  # longest a tip may lose the pen in a success [s]
    max_position_error: float = 0.005  # success: pen centre error throughout [m]
    effort_weight: float = 0.01  # weight of the effort penalty [-]
    contact_weight: float = 0.5  # weight of the contact-kept term [-]
    render_width: int = 480  # [px]
    render_height: int = 360  # [px]
    camera: str = "front"  # camera for rgb_array / depth_array: front, side, perspective
    # Disturbances (ias_gym.envs.disturbances; the robustness suite). Defaults: none.
    friction_scale: float = 1.0  # the pen's friction coefficient x this [-]
    mass_scale: float = 1.0  # the pen's mass and inertia x this [-]
    push_force: float = 0.0  # a push on the pen at a random time and direction [N]
    push_duration: float = 0.05  # how long the push lasts [s]
    force_noise: float = 0.0  # sigma of the measured contact forces' noise [N]
    joint_angle_noise: float = 0.0  # sigma of the measured joint angles' noise [rad]
    joint_velocity_noise: float = 0.0  # sigma of the measured joint velocities' noise [rad/s]
    action_noise: float = 0.0  # sigma of the noise on the normalised action [-]
    action_delay: int = 0  # control steps between an action and its effect [-]
    internal_force_step: float = 0.0  # internal-force reference steps of +- this [N]
    hand: str = DEFAULT_HAND  # the robot hand: a name of ias_gym.sim.hands.HANDS

    def __post_init__(self) -> None:
        get_hand(self.hand)  # InputError naming the known hands
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, float) and not math.isfinite(value):
                raise ValueError(f"{f.name} must be finite, got {value}")
        for name in ("control_dt", "duration", "max_contact_gap", "max_position_error"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in ("min_grasp_force", "pen_position_noise", "contact_noise", "penetration"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if self.drop_distance <= self.max_position_error:
            raise ValueError(
                f"drop_distance ({self.drop_distance} m) must exceed max_position_error "
                f"({self.max_position_error} m)"
            )
        if self.render_width < 1 or self.render_height < 1:
            raise ValueError("render_width and render_height must be >= 1 [px]")
        DisturbanceSettings.from_config(self).validate()

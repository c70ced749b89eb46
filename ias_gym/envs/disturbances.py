"""Disturbances of the pen tasks: what the robustness suite (``ias-gym robustness``) varies.

Every disturbance is a field of :class:`~ias_gym.envs.pen_hand_env.PenHandConfig`, so anyone
can use it with ``gym.make("IAS-PenRotate-v0", friction_scale=0.7)``. With the defaults
nothing here runs and the tasks are bit-identical to the undisturbed ones.

- **Model errors**: the pen's friction coefficient and its mass (with its inertia) scaled in
  the compiled model. A controller is not told: ``PenHandPhysics.pen_mass_nominal`` and
  ``pen_inertia(nominal=True)`` keep the values of the model as built, the ones a controller
  plans with.
- **A push**: a force on the pen's centre of mass for ``push_duration`` at a random time and
  in a random direction (uniform on the sphere).
- **Sensor noise**: Gaussian noise on the measured contact forces, joint angles and joint
  velocities, drawn once per control step. The observation carries it, and so do the
  measurements an expert reads (:meth:`SensorNoise.contact_intensities` etc.), so a
  privileged expert measures through the same noise as a learned policy.
- **Actuation**: Gaussian noise on the normalised action, and a delay of whole control steps.
- **Internal-force reference steps**: every ``INTERNAL_STEP_PERIOD`` the task asks for the
  grasp's internal forces ``f_int`` (eq. 7) to step by +-``internal_force_step`` along a
  random one of their directions; a controller reads it from
  :meth:`~ias_gym.envs.pen_hand_env.PenHandEnv.internal_force_reference`.

The disturbances draw from their own generator, seeded from the env's ``np_random`` at reset
only when one is enabled, so the undisturbed tasks' random streams stay as they were.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

#: Earliest and latest time of a push, from the start and the end of an episode [s].
PUSH_MARGIN = 0.5
#: How long each internal-force reference step holds [s]; the first starts after one period.
INTERNAL_STEP_PERIOD = 0.5
#: Internal-force directions of a grasp with four point contacts (12 - 6); k contacts have
#: 3k - 6 (``DisturbanceState.n_internal``).
N_INTERNAL = 6


@dataclasses.dataclass(frozen=True)
class DisturbanceSettings:
    """The disturbance fields of a pen task's configuration (see the module docstring).

    Attributes:
        friction_scale: the pen's friction coefficient x this [-].
        mass_scale: the pen's mass and inertia x this [-].
        push_force: magnitude of the push on the pen [N] (0: none).
        push_duration: its duration [s].
        force_noise: sigma of the noise on each measured contact-force component [N].
        joint_angle_noise: sigma on each measured joint angle [rad].
        joint_velocity_noise: sigma on each measured joint velocity [rad/s].
        action_noise: sigma of the noise added to the normalised action [-] (0.002 is
            1 mN m on the 0.5 N m motors).
        action_delay: control steps between an action and its effect [-].
        internal_force_step: size of the internal-force reference steps [N] (0: none).
    """

    friction_scale: float = 1.0
    mass_scale: float = 1.0
    push_force: float = 0.0
    push_duration: float = 0.05
    force_noise: float = 0.0
    joint_angle_noise: float = 0.0
    joint_velocity_noise: float = 0.0
    action_noise: float = 0.0
    action_delay: int = 0
    internal_force_step: float = 0.0

    @classmethod
    def from_config(cls, config: Any) -> DisturbanceSettings:
        """The disturbance fields of a task configuration."""
        return cls(**{f.name: getattr(config, f.name) for f in dataclasses.fields(cls)})

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first field out of its range."""
        for name in ("friction_scale", "mass_scale"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0, got {value}")
        for name in (
            "push_force",
            "force_noise",
            "joint_angle_noise",
            "joint_velocity_noise",
            "action_noise",
            "internal_force_step",
        ):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {value}")
        if not (np.isfinite(self.push_duration) and self.push_duration > 0):
            raise ValueError(f"push_duration must be finite and > 0 [s], got {self.push_duration}")
        if isinstance(self.action_delay, bool) or not isinstance(self.action_delay, int):
            raise ValueError(f"action_delay must be a whole number, got {self.action_delay!r}")
        if self.action_delay < 0:
            raise ValueError(f"action_delay must be >= 0 steps, got {self.action_delay}")

    @property
    def any(self) -> bool:
        """Whether any disturbance is enabled."""
        return self != DisturbanceSettings()

    @property
    def sensor_noise(self) -> bool:
        """Whether any measurement is noisy."""
        return bool(self.force_noise or self.joint_angle_noise or self.joint_velocity_noise)


@dataclasses.dataclass(frozen=True)
class SensorNoise:
    """The measurement noise of one control step (zeros when there is none).

    Attributes:
        force: ``(k, 3)`` added to each fingertip's measured force on the pen [N], paper frame.
        qpos: ``(n,)`` added to the measured hand joint angles [rad].
        qvel: ``(n,)`` added to the measured hand joint velocities [rad/s].
    """

    force: FloatArray
    qpos: FloatArray
    qvel: FloatArray

    @classmethod
    def zeros(cls, n_fingers: int, n_dofs: int) -> SensorNoise:
        """No noise."""
        return cls(np.zeros((n_fingers, 3)), np.zeros(n_dofs), np.zeros(n_dofs))

    def contact_intensities(self, c: FloatArray, frames: FloatArray) -> FloatArray:
        """Measured intensities ``c`` (per contact: normal, t1, t2) with the force noise."""
        result: FloatArray = c + np.einsum("kij,kj->ki", frames, self.force).reshape(-1)
        return result

    def tip_displacement(self, J: FloatArray, frames: FloatArray) -> FloatArray:
        """``(k, 3)`` apparent tip displacement [m] (paper frame) from the joint-angle noise.

        ``J`` maps joint velocities to contact-point velocities along each contact's frame
        (rows normal, t1, t2), so ``J dq`` is the displacement in those frames.
        """
        local = (J @ self.qpos).reshape(-1, 3)
        result: FloatArray = np.einsum("kji,kj->ki", frames, local)
        return result


class DisturbanceState:
    """One episode's disturbances: drawn at reset, applied around each step.

    Args:
        settings: what is enabled.
        n_fingers, n_dofs: the hand's size.
        control_dt: one env step [s].
        duration: the episode's length [s].
    """

    def __init__(
        self,
        settings: DisturbanceSettings,
        n_fingers: int,
        n_dofs: int,
        control_dt: float,
        duration: float,
    ) -> None:
        self.settings = settings
        self._n_fingers, self._n_dofs = n_fingers, n_dofs
        self._dt, self._duration = control_dt, duration
        self.noise = SensorNoise.zeros(n_fingers, n_dofs)
        self._rng = np.random.default_rng(0)
        self._push_start = np.inf
        self._push_direction = np.zeros(3)
        #: Internal-force directions of the hand's grasp (3 k - 6 for k point contacts).
        self.n_internal = 3 * n_fingers - 6
        self._internal_steps = np.zeros((0, self.n_internal))
        self._pending: list[FloatArray] = []

    def reset(self, np_random: np.random.Generator) -> None:
        """Draw the episode's push, internal-force steps and noise stream."""
        s = self.settings
        self._rng = np.random.default_rng(np_random.integers(2**63))
        if s.push_force > 0:
            latest = max(PUSH_MARGIN, self._duration - PUSH_MARGIN - s.push_duration)
            self._push_start = float(self._rng.uniform(PUSH_MARGIN, latest))
            direction = self._rng.normal(size=3)
            self._push_direction = direction / np.linalg.norm(direction)
        n_steps = int(self._duration / INTERNAL_STEP_PERIOD) + 1
        steps = np.zeros((n_steps, self.n_internal))
        if s.internal_force_step > 0:
            for k in range(1, n_steps):
                steps[k, self._rng.integers(self.n_internal)] = (
                    s.internal_force_step * self._rng.choice((-1.0, 1.0))
                )
        self._internal_steps = steps
        self._pending = [np.zeros(self._n_dofs)] * s.action_delay
        self.draw_noise()

    def draw_noise(self) -> None:
        """Draw this control step's measurement noise."""
        s = self.settings
        if not s.sensor_noise:
            return
        rng = self._rng
        self.noise = SensorNoise(
            rng.normal(0.0, s.force_noise, (self._n_fingers, 3)),
            rng.normal(0.0, s.joint_angle_noise, self._n_dofs),
            rng.normal(0.0, s.joint_velocity_noise, self._n_dofs),
        )

    def actuate(self, action: FloatArray) -> FloatArray:
        """The normalised action that reaches the motors this step (delayed, noisy, clipped)."""
        s = self.settings
        if s.action_delay:
            self._pending.append(action)
            action = self._pending.pop(0)
        if s.action_noise:
            action = action + self._rng.normal(0.0, s.action_noise, action.shape)
        return np.clip(action, -1.0, 1.0)

    def push(self, time: float) -> FloatArray:
        """The push force [N] (paper frame) during the control step that starts at ``time``."""
        s = self.settings
        # The push covers the steps whose start lies in [start, start + duration).
        if self._push_start <= time + 1e-9 < self._push_start + s.push_duration:
            result: FloatArray = s.push_force * self._push_direction
            return result
        return np.zeros(3)

    def internal_force_reference(self, time: float) -> FloatArray:
        """The internal-force reference offset ``f_int`` [N] at ``time`` (eq. 7's directions)."""
        k = min(int(time / INTERNAL_STEP_PERIOD + 1e-9), len(self._internal_steps) - 1)
        result: FloatArray = self._internal_steps[k]
        return result

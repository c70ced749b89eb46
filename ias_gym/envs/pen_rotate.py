"""IAS-PenRotate-v0: rotate the held pen about the paper's z-axis (a see-saw), centre at rest.

Paper section 4.3: ``r_d(t) = 0`` and the tilt follows ``phi_d(t) = A sin(w t)`` about z
(docs/NOTES.md: z is horizontal, across the pen, so the pen see-saws in the vertical x-y plane).
The paper's amplitude of 1 rad is out of reach for a hand of this size; the default
A = 0.2 rad at w = 2 rad/s lies inside the fingertips' workspace (+-1 cm vertically at the
contacts). As in Fig. 9, each episode starts with an angular error sampled at reset.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar

import numpy as np

from ias_gym.envs.layout import ObservationParts
from ias_gym.envs.pen_hand_env import (
    POSITION_SCALE,
    FloatArray,
    PenHandConfig,
    PenHandEnv,
    PenReference,
)
from ias_gym.sim.hands import get_hand

ORIENTATION_SCALE = 0.02  # [rad] scale of the tracking term


@dataclasses.dataclass(frozen=True)
class PenRotateConfig(PenHandConfig):
    """PenRotate settings (units in the comments); the base fields are shared with PenSlide."""

    amplitude: float = 0.2  # A [rad]
    frequency: float = 2.0  # w [rad/s]
    initial_error: tuple[float, float] = (0.03, 0.08)  # |tilt error| at reset, uniform [rad]
    settle_time: float = 1.0  # success ignores the first second [s]
    max_rms_error: float = 0.05  # success: RMS tilt error after settle_time, fraction of A
    track_weight: float = 1.0  # [-]
    position_weight: float = 1.0  # [-]

    def __post_init__(self) -> None:
        super().__post_init__()
        max_tilt = get_hand(self.hand).max_tilt
        if not 0 < self.amplitude <= max_tilt:
            raise ValueError(
                f"amplitude={self.amplitude} rad is outside (0, {max_tilt}] for hand "
                f"{self.hand!r}: the largest tilt the expert tracks on it (HandSpec.max_tilt)"
            )
        if not (self.frequency > 0 and self.max_rms_error > 0):
            raise ValueError("frequency [rad/s] and max_rms_error [-] must be > 0")
        lo, hi = self.initial_error
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo <= hi):
            raise ValueError(f"initial_error must be 0 <= low <= high [rad], got {(lo, hi)}")
        if not 0 <= self.settle_time < self.duration:
            raise ValueError(
                f"settle_time {self.settle_time} s must be in [0, duration {self.duration} s)"
            )


class PenRotateEnv(PenHandEnv):
    """Track a sinusoidal tilt of the pen about the paper's z-axis with its centre at rest.

    ## Description
    ``IAS-PenRotate-v0``: the fingers of a robot hand hold a pen and tilt it about the
    paper's z-axis along the target ``A sin(w t)`` (``amplitude``, ``frequency``) while its
    centre stays at rest. The hand (``hand``, :mod:`ias_gym.sim.hands`) is the four-finger
    ``"ias4f"`` (two fingers above the pen at -3 and +3 cm, two below at -2 and +2 cm) or
    the three-finger ``"ias3f"`` (two short fingers above at -3 and +3 cm, a long thumb
    below the centre); ``IAS-PenRotate3F-v0`` is this task with ``hand="ias3f"``.
    ``IAS-PenRotate-Shadow-v0`` runs it on the Shadow Dexterous Hand of Gymnasium-Robotics
    (``hand="shadow"``: first and little finger above the pen at -3.5 and +4 cm, the thumb
    below, ``amplitude`` 0.15 rad, the largest tilt the expert tracks on it from 2 to
    12 rad/s; needs ``pip install 'ias-gym[hands]'``). ``IAS-PenRotate-LEAP-v0`` runs it on
    the LEAP hand of MuJoCo Playground (``hand="leap"``: index and middle finger below the
    pen at +2.25 and -2.25 cm, the thumb on top, ``amplitude`` 0.075 rad, the largest tilt the
    expert tracks on it from 2 to 12 rad/s; needs ``pip install --no-deps
    playground==0.2.0``, which ``make setup`` runs).

    ## Action Space
    ``Box(-1, 1, (3k,))`` for a hand of k fingers: joint torques of its fingers in order
    (abd, mcp, pip each), normalised by each motor's limit. ``"ias4f"``: ``(12,)``, fingers
    1-4, 0.5 N m motors; ``"ias3f"``: ``(9,)``, fingers 1 (top left), 2 (the thumb, 0.8 N m
    motors) and 3 (top right; 0.35 N m motors on fingers 1 and 3); ``"shadow"``: ``(9,)``,
    the first finger, the thumb and the little finger, each motor's range that of the
    model's own actuator (0.72-2.37 N m); ``"leap"``: ``(9,)``, the index, the thumb and the
    middle finger, 0.22 N m motors (the model's). Values outside [-1, 1] are clipped; NaN/inf
    raise ValueError.

    ## Observation Space
    ``Box(-inf, inf, (12k + 19,))``, float64, paper frame, SI (``"ias4f"``: ``(55,)``,
    ``"ias3f"``: ``(46,)``): hand joint angles (3k) and velocities (3k); pen centre
    relative to nominal (3), the pen's axis as a unit vector (3), its linear (3) and
    angular velocity (3); the net force of each fingertip on the pen (k x 3); episode time
    fraction (1); the tilt error, target tilt and target tilt rate about z (3); the pen's
    rotation error about the vertical y (1); sin and cos of w t (2).

    By name: ``env.unwrapped.observation_layout[name]`` is the part's slice
    (:attr:`~ias_gym.envs.pen_hand_env.PenHandEnv.observation_parts` in order); k fingers:

    | name | size | content |
    |---|---|---|
    | ``joint_angles`` | 3k | hand joint angles [rad], the hand's joint order |
    | ``joint_velocities`` | 3k | their velocities [rad/s] |
    | ``pen_position`` | 3 | pen centre relative to nominal [m] |
    | ``pen_axis`` | 3 | unit vector along the pen's axis |
    | ``pen_velocity`` | 3 | pen centre velocity [m/s] |
    | ``pen_omega`` | 3 | pen angular velocity [rad/s] |
    | ``tip_forces`` | 3k | net force of each fingertip on the pen, 3 per finger [N] |
    | ``time_fraction`` | 1 | time since reset / episode duration |
    | ``tilt_error`` | 1 | the tilt error about z [rad] |
    | ``target_tilt`` | 1 | the target tilt ``A sin(w t)`` [rad] |
    | ``target_tilt_rate`` | 1 | its rate [rad/s] |
    | ``turn_error`` | 1 | the pen's rotation error about the vertical y [rad] |
    | ``target_phase`` | 2 | sin and cos of w t |

    ## Rewards
    Sum of named terms, each in ``info["reward_<name>"]``: ``track`` =
    exp(-(e_z^2 + e_y^2) / (0.02 rad)^2) with e_z the tilt error about z and e_y the error
    about the vertical axis, ``position`` = exp(-(|r| / 5 mm)^2), ``contact`` = 0.5 x
    fraction of tips touching, ``effort`` = -0.01 x mean(action^2).

    ## Starting State
    A stable grasp, perturbed: the pen centre uniform within +-``pen_position_noise`` per
    axis of nominal, tilted about z by a tilt error of random sign and size uniform in
    ``initial_error``, the contacts at the hand's nominal positions along the pen
    (``"ias4f"``: [-3, -2, 2, 3] cm, ``"ias3f"``: [-3, 0, 3] cm), each uniform within
    +-``contact_noise``, the tips pressed ``penetration`` into the pen.
    ``reset(options={"qpos": ..., "qvel": ...})`` starts from that exact MuJoCo state instead.

    ## Episode End
    ``info["is_success"]`` (at the last step): RMS tilt error after the first second < 5 %
    of A, pen centre within 5 mm throughout, no tip off the pen for more than 20 ms, never
    dropped. Terminated when the pen is dropped (centre more than 2 cm from nominal);
    truncated by the time limit (400 steps of 10 ms) or a diverging simulation
    (``info["sim_unstable"]``).

    ## Arguments
    ``gym.make("ID", **kwargs)`` takes ``render_mode`` (``"human"``, ``"rgb_array"``,
    ``"depth_array"``) and these fields of its config (defaults in brackets):

    - ``control_dt`` [0.01 s]: one env step, a multiple of the physics step (1 ms; 2 ms on
      the Shadow hand).
    - ``min_grasp_force`` [0.2 N]: minimum normal force a controller should keep.
    - ``pen_position_noise`` [0.001 m], ``contact_noise`` [0.001 m], ``penetration``
      [3e-4 m]: the reset distribution (see Starting State).
    - ``drop_distance`` [0.02 m]: pen centre this far from nominal = dropped.
    - ``max_contact_gap`` [0.02 s], ``max_position_error`` [0.005 m]: success limits.
    - ``effort_weight`` [0.01], ``contact_weight`` [0.5]: reward weights [-].
    - ``render_width`` [480 px], ``render_height`` [360 px], ``camera`` [``"front"``;
      ``"side"``, ``"perspective"``]: the rendered frames.
    - Disturbances (:mod:`ias_gym.envs.disturbances`; the defaults disturb nothing):
      ``friction_scale`` [1.0, -] and ``mass_scale`` [1.0, -] scale the pen's friction
      coefficient and its mass and inertia; ``push_force`` [0 N] pushes the pen for
      ``push_duration`` [0.05 s] at a random time and direction; ``force_noise`` [0 N],
      ``joint_angle_noise`` [0 rad] and ``joint_velocity_noise`` [0 rad/s] are the sigmas of
      the measurement noise; ``action_noise`` [0, -] the sigma of the noise on the
      normalised action; ``action_delay`` [0 control steps] delays every action;
      ``internal_force_step`` [0 N] steps the internal-force reference by +- this.
    - ``hand`` [``"ias4f"``; ``"ias3f"``; ``"shadow"``; ``"leap"``]: the robot hand
      (:mod:`ias_gym.sim.hands`); an unknown name raises InputError listing the known ones,
      and ``"shadow"`` or ``"leap"`` without its package one naming how to install it.
    - PenRotate's own: ``duration`` [4.0 s]; ``amplitude`` A [0.2 rad; 0.15 rad on
      ``IAS-PenRotate-Shadow-v0``, 0.075 rad on ``IAS-PenRotate-LEAP-v0``; at most the
      hand's ``max_tilt``: 0.35 rad for ``"ias4f"``, 0.4 rad for ``"ias3f"``, 0.15 rad for
      ``"shadow"``, 0.075 rad for ``"leap"``];
      ``frequency`` w [2.0 rad/s]; ``initial_error`` [(0.03, 0.08) rad]: the range of the
      reset's tilt error; ``settle_time`` [1.0 s] and ``max_rms_error`` [0.05, fraction of
      A]: the success test ignores the first ``settle_time``; ``track_weight`` [1.0] and
      ``position_weight`` [1.0]: reward weights [-].

    ## Version History
    - v0: initial release; the ``hand`` argument, ``IAS-PenRotate3F-v0``,
      ``IAS-PenRotate-Shadow-v0`` and ``IAS-PenRotate-LEAP-v0`` added later (the four-finger
      default is unchanged).
    """

    config_class: ClassVar[type[PenHandConfig]] = PenRotateConfig
    config: PenRotateConfig
    _episode_fields: ClassVar[tuple[str, ...]] = (
        *PenHandEnv._episode_fields,
        "_sq_error_sum",
        "_sq_error_count",
        "_errors",
    )

    _sq_error_sum: float
    _sq_error_count: int
    _errors: tuple[float, float]

    def target(self, t: float | None = None) -> tuple[float, float]:
        """Target tilt about z, ``A sin(w t)`` [rad], and its rate [rad/s]."""
        cfg = self.config
        t = self.time if t is None else t
        return (
            cfg.amplitude * math.sin(cfg.frequency * t),
            cfg.amplitude * cfg.frequency * math.cos(cfg.frequency * t),
        )

    def reference(self) -> PenReference:
        """Pen centre at rest, axis tilted by ``A sin(w t)`` about z (sec. 4.3)."""
        cfg = self.config
        angle, rate = self.target()
        accel = -(cfg.frequency**2) * angle
        zero = np.zeros(3)
        return PenReference(
            position=zero,
            velocity=zero,
            acceleration=zero,
            axis=np.array([np.cos(angle), np.sin(angle), 0.0]),
            omega=np.array([0.0, 0.0, rate]),
            alpha=np.array([0.0, 0.0, accel]),
            sliding={},
        )

    def tilt_errors(self) -> tuple[float, float]:
        """Rotation errors [rad]: about z (the tracked tilt) and about the vertical y.

        Computed from the pen's axis, so they do not depend on the pen's roll about itself.
        """
        x, y, z = self.state.axis.tolist()
        return math.atan2(y, x) - self.target()[0], math.atan2(-z, math.hypot(x, y))

    def _sample_initial_pose(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        position, rpy, contact_x = super()._sample_initial_pose()
        lo, hi = self.config.initial_error
        # The sign as rng.choice([-1.0, 1.0]) draws it (numpy's choice with replacement is
        # integers(0, 2)), the same bits without its 4 us of argument handling.
        sign = (-1.0, 1.0)[self.np_random.integers(0, 2)]
        rpy[2] = sign * self.np_random.uniform(lo, hi)
        return position, rpy, contact_x

    def _task_update(self) -> None:
        if self._steps == 0:
            self._sq_error_sum, self._sq_error_count = 0.0, 0
        self._errors = self.tilt_errors()
        if self.time >= self.config.settle_time - 1e-9 and self._steps > 0:
            self._sq_error_sum += self._errors[0] ** 2
            self._sq_error_count += 1

    def rms_error(self) -> float:
        """RMS tilt error about z after ``settle_time`` so far [rad] (0 before any sample)."""
        if self._sq_error_count == 0:
            return 0.0
        return float(np.sqrt(self._sq_error_sum / self._sq_error_count))

    def _task_observation(self) -> FloatArray:
        target, rate = self.target()
        w_t = self.config.frequency * self.time
        return np.array(
            [self._errors[0], target, rate, self._errors[1], math.sin(w_t), math.cos(w_t)]
        )

    def _task_observation_parts(self) -> ObservationParts:
        return (
            ("tilt_error", 1),
            ("target_tilt", 1),
            ("target_tilt_rate", 1),
            ("turn_error", 1),
            ("target_phase", 2),
        )

    def _task_reward(self) -> dict[str, float]:
        cfg = self.config
        e_z, e_y = self._errors
        r = self.state.position_error / POSITION_SCALE
        return {
            "track": cfg.track_weight * math.exp(-(e_z**2 + e_y**2) / ORIENTATION_SCALE**2),
            "position": cfg.position_weight * math.exp(-r * r),
        }

    def _task_success(self) -> bool:
        return bool(self.rms_error() < self.config.max_rms_error * self.config.amplitude)

    def episode_metrics(self, info: dict[str, Any]) -> dict[str, float]:
        """Error metrics of a finished episode from its last ``info`` (SI units).

        The RMS tilt error is NaN for an episode that ended before ``settle_time``.
        """
        rms = float(info["rms_tilt_error"]) if self._sq_error_count else float("nan")
        return {
            "rms_tilt_error": rms,
            "rms_tilt_error_fraction": rms / self.config.amplitude,
            "max_position_error": float(info["max_position_error"]),
        }

    def _task_info(self) -> dict[str, Any]:
        return {
            "tilt_error": self._errors[0],
            "turn_error": self._errors[1],
            "rms_tilt_error": self.rms_error(),
        }

"""IAS-PenSlide-v0: four fingers slide outward along a held pen, one after another.

The skill example of paper sections 3.2 and 4.2. After a short hold, finger i slides 1 cm
outward during phase i (eq. 17 with the paper's parameters: l = [3, 2, 2, 3] cm,
alpha_i = 1 cm/s, phases of 1 s): fingers 1 and 2 to -x, fingers 3 and 4 to +x (the
equation's direction; the paper's prose says "to the left" for all, see docs/NOTES.md), while
the pen stays still.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar

import numpy as np

from ias_gym.envs.layout import ObservationParts
from ias_gym.envs.pen_hand_env import (
    ANGLE_SCALE,
    POSITION_SCALE,
    FloatArray,
    PenHandConfig,
    PenHandEnv,
    PenReference,
)
from ias_gym.errors import InputError
from ias_gym.grasp.pen_skill import (
    OUTWARD,
    PenSkillParams,
    finger_distances,
    finger_velocities,
    sliding_directions,
)
from ias_gym.sim.hands import get_hand

#: The paper's skill (section 4.2); the task's schedule.
SKILL = PenSkillParams()
TRACK_SCALE = 0.003  # [m] scale of the schedule-tracking term
_PHASES = np.eye(6)  # one-hot rows: hold, phases 1-4, settle


@dataclasses.dataclass(frozen=True)
class PenSlideConfig(PenHandConfig):
    """PenSlide settings (units in the comments); the base fields are shared with PenRotate."""

    hold_time: float = 0.25  # hold before phase 1 starts [s]
    duration: float = 4.75  # hold + 4 s of sliding + 0.5 s settling [s]
    target_tolerance: float = 0.002  # success: each finger this close to its target [m]
    max_tilt: float = math.radians(5.0)  # success: pen tilt throughout [rad]
    track_weight: float = 1.0  # [-]
    pose_weight: float = 1.0  # [-]

    def __post_init__(self) -> None:
        super().__post_init__()
        hand = get_hand(self.hand)
        if hand.contact_x != get_hand("ias4f").contact_x:
            # The schedule of eq. (17) names four contacts (l = [3, 2, 2, 3] cm, each sliding
            # outward in its own phase); on a hand with other contacts it is another skill.
            raise InputError(
                f"PenSlide runs the paper's four-finger sliding schedule (eq. 17); hand "
                f"{self.hand!r} has contacts at {list(hand.contact_x)} m, not the schedule's "
                "[-0.03, -0.02, 0.02, 0.03]: use hand='ias4f' (a skill moves to another hand "
                "through its grip transform, docs/DESIGN.md 'The second hand')"
            )
        if self.hold_time < 0:
            raise ValueError(f"hold_time must be >= 0 [s], got {self.hold_time}")
        end = self.hold_time + SKILL.phase_times[-1]
        # Success is judged at the last step against the final targets: an episode that ends
        # before every finger has slid would be judged on a schedule it never ran.
        if self.duration < end - 1e-9:
            raise ValueError(
                f"duration {self.duration} s ends before the sliding schedule does "
                f"(hold_time {self.hold_time} s + {SKILL.phase_times[-1]} s = {end} s); "
                f"use duration >= {end}"
            )
        if self.target_tolerance <= 0 or self.max_tilt <= 0:
            raise ValueError("target_tolerance [m] and max_tilt [rad] must be > 0")


class PenSlideEnv(PenHandEnv):
    """The fingers slide outward along the pen in turn while the pen stays still.

    ## Description
    The skill example of paper sections 3.2 and 4.2 (``IAS-PenSlide-v0``): four fingers
    hold a pen; after ``hold_time`` finger i slides 1 cm outward during phase i (eq. 17:
    l = [3, 2, 2, 3] cm, alpha_i = 1 cm/s, phases of 1 s), fingers 1 and 2 to -x, fingers 3
    and 4 to +x, while the pen stays still.

    ## Action Space
    ``Box(-1, 1, (12,))``: joint torques of fingers 1-4 (abd, mcp, pip), normalised by the
    motors' limit (0.5 N m). Values outside [-1, 1] are clipped; NaN/inf raise ValueError.

    ## Observation Space
    ``Box(-inf, inf, (67,))``, float64, paper frame (x pen axis, y up, z lateral), SI:
    hand joint angles (12) and velocities (12); pen centre relative to nominal (3), the
    pen's axis as a unit vector (3; roll about the axis is irrelevant here and omitted),
    its linear (3) and angular velocity (3); the net force of each fingertip on the pen
    (4 x 3, MuJoCo contact sensors); episode time fraction (1); per finger its position
    along the pen minus its target (4) and the target's rate (4); the phase as one-hot
    (hold, phases 1-4, settle: 6); the targets along the pen (4).

    By name: ``env.unwrapped.observation_layout[name]`` is the part's slice
    (:attr:`~ias_gym.envs.pen_hand_env.PenHandEnv.observation_parts` in order):

    | name | size | content |
    |---|---|---|
    | ``joint_angles`` | 12 | hand joint angles [rad], the hand's joint order |
    | ``joint_velocities`` | 12 | their velocities [rad/s] |
    | ``pen_position`` | 3 | pen centre relative to nominal [m] |
    | ``pen_axis`` | 3 | unit vector along the pen's axis |
    | ``pen_velocity`` | 3 | pen centre velocity [m/s] |
    | ``pen_omega`` | 3 | pen angular velocity [rad/s] |
    | ``tip_forces`` | 12 | net force of each fingertip on the pen, 3 per finger [N] |
    | ``time_fraction`` | 1 | time since reset / episode duration |
    | ``slide_error`` | 4 | each finger's position along the pen minus its target [m] |
    | ``slide_target_rate`` | 4 | the targets' rates [m/s] |
    | ``phase`` | 6 | one-hot: hold, phases 1-4, settle |
    | ``slide_target`` | 4 | the targets along the pen [m] |

    ## Rewards
    The sum of named terms, each copied into ``info["reward_<name>"]``:
    ``track`` = mean_i exp(-(e_i / 3 mm)^2) (e_i: finger i's position along the pen minus
    its scheduled position), ``pose`` = exp(-(|r| / 5 mm)^2 - (tilt / 5 deg)^2),
    ``contact`` = 0.5 x fraction of tips touching, ``effort`` = -0.01 x mean(action^2).

    ## Starting State
    A stable grasp, perturbed: the pen centre uniform within +-``pen_position_noise`` per
    axis of nominal, the contacts at [-3, -2, 2, 3] cm along the pen, each uniform within
    +-``contact_noise``, the tips pressed ``penetration`` into the pen.
    ``reset(options={"qpos": ..., "qvel": ...})`` starts from that exact MuJoCo state instead.

    ## Episode End
    ``info["is_success"]`` (at the last step): every finger within 2 mm of its final target,
    pen centre error < 5 mm and tilt < 5 deg throughout, no tip off the pen for more than
    20 ms. Terminated when the pen is dropped (centre more than 2 cm from nominal);
    truncated by the time limit (475 steps of 10 ms) or when the simulation diverges
    (``info["sim_unstable"]``).

    ## Arguments
    ``gym.make("ID", **kwargs)`` takes ``render_mode`` (``"human"``, ``"rgb_array"``,
    ``"depth_array"``) and these fields of its config (defaults in brackets):

    - ``control_dt`` [0.01 s]: one env step, a multiple of the 1 ms physics step.
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
    - ``hand`` [``"ias4f"``]: the robot hand (:mod:`ias_gym.sim.hands`). The sliding
      schedule is the paper's four-finger one, so only ``"ias4f"`` is accepted; another name
      raises InputError. There is no three-finger PenSlide: ``"ias3f"``'s thumb, its only
      finger below the pen, cannot slide along a still pen (its kinetic friction exceeds
      what the top fingers can hold by mu m g; docs/DESIGN.md, "The second hand").
    - PenSlide's own: ``hold_time`` [0.25 s] before phase 1; ``duration`` [4.75 s]: hold +
      4 s of sliding + 0.5 s settling; ``target_tolerance`` [0.002 m] and ``max_tilt``
      [5 deg, in rad]: success limits; ``track_weight`` [1.0] and ``pose_weight`` [1.0]:
      reward weights [-].

    ## Version History
    - v0: initial release.
    """

    config_class: ClassVar[type[PenHandConfig]] = PenSlideConfig
    config: PenSlideConfig
    _episode_fields: ClassVar[tuple[str, ...]] = (
        *PenHandEnv._episode_fields,
        "_max_tilt",
        "_slide_errors",
    )

    _max_tilt: float
    _slide_errors: FloatArray
    _reference_step: int = -1  # the step _reference was made for (a cache)

    def __init__(self, render_mode: str | None = None, **config: Any) -> None:
        """Build the task; ``config``: fields of :class:`PenSlideConfig` to override."""
        super().__init__(render_mode, **config)
        # The schedule at every step time, computed once: [-phi1, -phi2, +phi3, +phi4] (eq. 17).
        steps = np.arange(self.max_steps + 1) * self.config.control_dt - self.config.hold_time
        self._target_table = OUTWARD * finger_distances(steps, SKILL)
        self._target_rate_table = OUTWARD * finger_velocities(steps, SKILL)
        self._phase_table = [self._phase_at(t) for t in steps]
        # The part of the observation that depends on time only: rates, phase, targets.
        self._schedule_obs = np.column_stack(
            [self._target_rate_table, _PHASES[self._phase_table], self._target_table]
        )
        self._task_update()

    def schedule_time(self) -> float:
        """Time on the paper's schedule, ``t - hold_time`` [s] (negative while holding)."""
        return self.time - self.config.hold_time

    def targets(self) -> tuple[FloatArray, FloatArray]:
        """Scheduled contact positions along the pen [m] and their rates [m/s] now (eq. 17).

        Signed as the pen-frame x coordinate: ``[-phi1, -phi2, +phi3, +phi4]``.
        """
        k = min(self._steps, self.max_steps)
        if not hasattr(self, "_target_table"):  # during the base class's __init__
            t = self.schedule_time()
            return OUTWARD * finger_distances(t, SKILL), OUTWARD * finger_velocities(t, SKILL)
        return self._target_table[k], self._target_rate_table[k]

    def reference(self) -> PenReference:
        """Pen at rest, untilted; the scheduled finger sliding (eq. 17)."""
        k = min(self._steps, self.max_steps)
        if k != self._reference_step:
            self._reference_step, self._reference = k, self._reference_now()
        return self._reference

    def _reference_now(self) -> PenReference:
        zero = np.zeros(3)
        target, velocity = self.targets()
        return PenReference(
            position=zero,
            velocity=zero,
            acceleration=zero,
            axis=np.array([1.0, 0.0, 0.0]),
            omega=zero,
            alpha=zero,
            sliding=sliding_directions(self.schedule_time(), SKILL),
            contact_x=target,
            contact_vx=velocity,
        )

    def phase(self) -> int:
        """0 while holding, i during phase i (1-4), 5 when settling."""
        if not hasattr(self, "_phase_table"):  # during the base class's __init__
            return self._phase_at(self.schedule_time())
        return self._phase_table[min(self._steps, self.max_steps)]

    @staticmethod
    def _phase_at(tau: float) -> int:
        if tau < 0:
            return 0
        return min(int(np.searchsorted(SKILL.phase_times, tau, side="right")), 5)

    def _task_update(self) -> None:
        target, _ = self.targets()
        self._slide_errors = self.state.tip_x - target
        tilt = self.state.tilt
        self._max_tilt = tilt if self._steps == 0 else max(self._max_tilt, tilt)

    def _task_observation(self) -> FloatArray:
        if not hasattr(self, "_schedule_obs"):  # during the base class's __init__
            target, velocity = self.targets()
            return np.concatenate([self._slide_errors, velocity, _PHASES[self.phase()], target])
        return np.concatenate(
            [self._slide_errors, self._schedule_obs[min(self._steps, self.max_steps)]]
        )

    def _task_observation_parts(self) -> ObservationParts:
        n = len(self._nominal_contact_x)
        return (("slide_error", n), ("slide_target_rate", n), ("phase", 6), ("slide_target", n))

    def _task_reward(self) -> dict[str, float]:
        cfg = self.config
        s = self.state
        track = sum(math.exp(-((e / TRACK_SCALE) ** 2)) for e in self._slide_errors.tolist())
        pose = (s.position_error / POSITION_SCALE) ** 2 + (s.tilt / ANGLE_SCALE) ** 2
        return {
            "track": cfg.track_weight * track / len(self._slide_errors),
            "pose": cfg.pose_weight * math.exp(-pose),
        }

    def _task_success(self) -> bool:
        cfg = self.config
        return bool(
            float(np.abs(self._slide_errors).max()) < cfg.target_tolerance
            and self._max_tilt < cfg.max_tilt
        )

    def episode_metrics(self, info: dict[str, Any]) -> dict[str, float]:
        """Error metrics of a finished episode from its last ``info`` (SI units)."""
        return {
            "final_slide_error": float(np.abs(info["slide_errors"]).max()),
            "max_position_error": float(info["max_position_error"]),
            "max_pen_tilt": float(info["max_pen_tilt"]),
        }

    def _task_info(self) -> dict[str, Any]:
        return {
            "slide_errors": self._slide_errors.copy(),
            "pen_tilt": self.state.tilt,
            "max_pen_tilt": self._max_tilt,
            "phase": self.phase(),
        }

"""The settings of ``IAS-GloveGrasp-v0`` (:class:`GloveGraspConfig`), checked when made.

The fields are the env's ``gym.make`` keywords besides ``render_mode``, ``person``,
``calibration`` and ``glove_factory`` (:class:`~ias_gym.envs.glove_grasp.GloveGraspEnv`);
the glove-assist and hardware envs take the same.
"""

from __future__ import annotations

import dataclasses

from ias_gym.errors import InputError
from ias_gym.glove.ids import check_id
from ias_gym.glove.operator import OPERATORS
from ias_gym.glove.skills import check_skill


@dataclasses.dataclass(frozen=True)
class GloveGraspConfig:
    """Settings of :class:`~ias_gym.envs.glove_grasp.GloveGraspEnv` (units in the comments)."""

    person_id: str = "p1"  # simulated person wearing the glove (PersonParams.sample)
    skill: str | None = None  # object skill after the pinch-lift (glove.skills.SKILLS)
    operator: str = "closed_loop"  # the simulated person: "closed_loop" or the open "script"
    control_dt: float = 0.01  # one env step = one glove read [s]; a multiple of 1 ms
    duration: float = 4.0  # episode length [s] (registered max_episode_steps = 400)
    action_scale: float = 0.2  # joint offset of a full action [rad]
    filter_tau: float = 0.05  # time constant of the low-pass on the calibrated Θ [s]; 0: off
    lift_height: float = 0.03  # success: pen centre this much above its start [m]
    drop_height: float = 0.05  # terminated: pen centre this far below its start [m]
    max_distance: float = 0.15  # terminated: pen centre this far from its start [m]
    lift_weight: float = 1.0  # weight of the lift term [-]
    track_weight: float = 1.0  # weight of the skill's tilt-tracking term [-] (with a skill)
    contact_weight: float = 0.5  # weight of the pinch-contact term [-]
    effort_weight: float = 0.1  # weight of the action-effort penalty [-]

    def __post_init__(self) -> None:
        # person_id names the cached profile file: checked before anything is built.
        check_id(self.person_id, "person_id")
        if self.skill is not None:
            check_skill(self.skill, "skill")
        if self.operator not in OPERATORS:
            raise InputError(
                f"operator {self.operator!r} is not known; choose one of {', '.join(OPERATORS)}"
            )
        if self.control_dt <= 0 or self.duration <= 0:
            raise ValueError("control_dt and duration must be positive [s]")

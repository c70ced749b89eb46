"""A stored skill as a robot hand executes it, and the reader that builds it from a store.

:class:`SkillReference` holds one skill on the env's control grid (pen trajectory, grasp
margin, tolerances). ``IAS-PenSkill-v0`` gets its references from a
:data:`ReferenceReader`: any function ``reader(skill_db, skill_ids, hand, control_dt,
duration) -> list[SkillReference]``. The default reader opens a skill database
(:func:`ias_gym.skills.transfer.load_references`); it lives in the skills layer, above the
envs, so the env looks it up by name when it needs it (:func:`default_reader`), as Gymnasium
looks up an env's entry point. Pass ``reader=`` to read another store.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import cast

import numpy as np

from ias_gym.envs.pen_hand_env import FloatArray, PenReference
from ias_gym.errors import InputError

#: ``reader(skill_db, skill_ids, hand, control_dt, duration)`` -> the skills' references.
ReferenceReader = Callable[
    [str | Path | None, Sequence[int] | None, str, float, float | None], list["SkillReference"]
]
#: The default reader, ``module:function`` (the skill database's, in the skills layer).
DEFAULT_READER = "ias_gym.skills.transfer:load_references"


def default_reader() -> ReferenceReader:
    """The skill database's reader (:data:`DEFAULT_READER`), imported on first use."""
    module, name = DEFAULT_READER.split(":")
    return cast(ReferenceReader, getattr(importlib.import_module(module), name))


@dataclasses.dataclass(frozen=True, eq=False)
class SkillReference:
    """One skill as the target hand should execute it: arrays on the env's control grid.

    Row k is time ``k dt`` after the grasp is established (the skill's own start); paper
    frame, SI units, the pen's position relative to its nominal centre in the hand.

    Attributes:
        dt: sample period [s] (the env's ``control_dt``).
        position, velocity, acceleration: ``(T, 3)`` pen centre [m], [m/s], [m/s^2].
        axis: ``(T, 3)`` unit pen axis (its roll is free).
        omega, alpha: ``(T, 3)`` angular velocity [rad/s] and acceleration [rad/s^2].
        margin: ``(T,)`` grasp margin to hold [-] (:mod:`ias_gym.grasp.grasp_margin`).
        skill_id: the skill's id in its database (-1: none).
        name: the skill's name; person: who demonstrated it ("" if unknown).
        scale: translation scale into the hand's workspace [-].
        scale_rotation: rotation scale [-].
        tolerance_rotation, tolerance_position, tolerance_margin: how far an execution may
            stay from this reference and succeed: RMS axis angle [rad], RMS centre
            distance [m], mean relative margin error [-] (``None``: the env's defaults;
            :mod:`ias_gym.skills.tolerance` sets them from the person's repeatability).
    """

    dt: float
    position: FloatArray
    velocity: FloatArray
    acceleration: FloatArray
    axis: FloatArray
    omega: FloatArray
    alpha: FloatArray
    margin: FloatArray
    skill_id: int = -1
    name: str = ""
    person: str = ""
    scale: float = 1.0
    scale_rotation: float = 1.0
    tolerance_rotation: float | None = None
    tolerance_position: float | None = None
    tolerance_margin: float | None = None

    def __post_init__(self) -> None:
        T = len(self.position)
        for name in ("tolerance_rotation", "tolerance_position", "tolerance_margin"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise InputError(f"skill reference {name} must be None or > 0, got {value}")
        if T < 2 or not (math.isfinite(self.dt) and self.dt > 0):
            raise InputError(f"a skill reference needs >= 2 samples and dt > 0, got {T}, {self.dt}")
        for name in ("position", "velocity", "acceleration", "axis", "omega", "alpha"):
            value = np.asarray(getattr(self, name), dtype=float)
            if value.shape != (T, 3) or not np.all(np.isfinite(value)):
                raise InputError(
                    f"skill reference {name} must be finite with shape ({T}, 3), got {value.shape}"
                )
            object.__setattr__(self, name, value)
        margin = np.asarray(self.margin, dtype=float)
        if margin.shape != (T,) or not np.all(np.isfinite(margin)) or np.any(margin <= 0):
            raise InputError(f"skill reference margin must be ({T},), finite and > 0")
        object.__setattr__(self, "margin", margin)
        norms = np.linalg.norm(self.axis, axis=1)
        if np.any(np.abs(norms - 1.0) > 1e-6):
            raise InputError("skill reference axis must be unit vectors")

    @property
    def length(self) -> int:
        """Number of samples T."""
        return len(self.position)

    @property
    def duration(self) -> float:
        """Time spanned [s]."""
        return (self.length - 1) * self.dt

    def index(self, t: float) -> int:
        """The sample at time ``t`` [s] (the last one after the end: the pose is held)."""
        return min(max(round(t / self.dt), 0), self.length - 1)

    def at(self, t: float) -> PenReference:
        """The :class:`PenReference` the expert tracks at time ``t`` [s]."""
        k = self.index(t)
        end = k == self.length - 1 and t > self.duration  # held at rest after the skill
        zero = np.zeros(3)
        return PenReference(
            position=self.position[k],
            velocity=zero if end else self.velocity[k],
            acceleration=zero if end else self.acceleration[k],
            axis=self.axis[k],
            omega=zero if end else self.omega[k],
            alpha=zero if end else self.alpha[k],
            sliding={},
        )

"""The scripted operator of the glove world: the person pinching and lifting the pen.

:func:`pen_operator` adapts :class:`~ias_gym.glove.device.ReachPinchLift` (the glove's bare-pad
pinch) to a pen of a given radius, and :class:`FromPreShape` starts it where the episodes of
``IAS-GloveGrasp-v0`` begin. Pure hand geometry (numpy and :mod:`ias_gym.glove.hand`): the
pen's radius comes from the caller, who reads it from the compiled scene
(:mod:`ias_gym.sim.glove_scene`), so no number of the MJCF is copied here.
"""

from __future__ import annotations

import dataclasses
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from ias_gym.errors import PersonCannotError
from ias_gym.glove.device import ReachPinchLift, ReachPinchLiftTimings
from ias_gym.glove.hand import PersonParams
from ias_gym.glove.skills import SKILL_PINCH_FORCE, SKILL_TIMINGS, SkillOperator

FloatArray = NDArray[np.float64]

#: Tip-to-tip distance of the operator's pen pinch minus the pen's diameter, at scale 1 [m].
#: The model's pads need +13 mm (index 6 mm + thumb 7 mm radius); the targets lie 17 mm
#: (+ ReachPinchLift's 2 mm) further in, so the position servos squeeze the pen with about
#: 2 N (measured; the pen weighs 1 N, mu = 0.25).
PEN_PAD_GAP = -0.004
#: Pen pinches (thumb CMC, thumb flexion, index DIP) [rad], the first in reach (and in the
#: person's range of motion) is used: poses inside the calibration sessions' pinch range. The
#: last, less opposed one is the pinch of a thumb whose range of motion is a fifth below the
#: population's (``range_of_motion`` < 0.84: 4 % of persons, whose thumb cannot reach 1.0).
#: A thumb less opposed than 1.1 rad leaves the index more flexed on the pen (MCP 0.4-0.6
#: rad instead of 0.7-0.8), which holds it more loosely in a tilt (measured).
PEN_PINCH_POSES: tuple[tuple[float, float, float], ...] = (
    (1.1, 0.4, 0.4),
    (1.0, 0.4, 0.4),
    (1.0, 0.6, 0.6),
    (1.1, 0.4, 0.2),
    (1.0, 0.2, 0.4),
    (0.9, 0.4, 0.4),
)


#: ReachPinchLift's default phase times (the pinch-lift without a skill).
DEFAULT_TIMINGS = ReachPinchLiftTimings()
#: ReachPinchLift's default pinch force [N].
DEFAULT_PINCH_FORCE = 2.0


def pen_operator(
    person: PersonParams,
    pen_radius: float,
    timings: ReachPinchLiftTimings = DEFAULT_TIMINGS,
    pinch_force: float = DEFAULT_PINCH_FORCE,
) -> ReachPinchLift:
    """The scripted operator pinching the pen: :class:`ReachPinchLift` with the pads apart.

    ReachPinchLift puts the index tip ``pad_contact - force / pad_stiffness`` [m] from the
    thumb tip along the thumb pad's normal (the glove's pinch of the bare pads); for the pen
    this gap is set to the pen's diameter + :data:`PEN_PAD_GAP` (a person whose
    ``pad_contact`` is the pen's width), so the index comes down on the pen right across from
    the thumb pad: an antipodal pinch whose squeeze passes through the pen's axis (with the
    bare-pad pinch, the pads meet at 110 degrees around the pen and squeeze it out). That
    holds in the person's planar hand; in the scene's hand the thumb's opposition turns its
    pad out of the index's plane, and in the holds the measured contact normals are about
    90 degrees apart: the thumb's pad carries the pen from below (about its weight), the
    index presses on its side (0.1-0.5 N), so a deeper pinch rolls the pen more than it
    squeezes it (see :data:`PEN_PINCH_POSES`). The
    glove still reads the real person (no pad contact, no pinch cross-talk: the pads touch
    the pen, not each other). The thumb is more opposed than in the default pinch
    (:data:`PEN_PINCH_POSES`) so that the index reaches across a 2 cm pen.

    Args:
        person: the operator's hand.
        pen_radius: the pen's radius [m] (the scene's pen geom, ``model.geom_size[pen, 0]``).
        timings: the script's phase times [s] (a skill's: :data:`SKILL_TIMINGS`).
        pinch_force: ReachPinchLift's ``pinch_force`` [N] (how far the targets lie inside
            the pen; a skill's: :data:`~ias_gym.glove.skills.SKILL_PINCH_FORCE`).

    Raises:
        ValueError: ``pen_radius`` is not positive.
        PersonCannotError: no pen pinch of :data:`PEN_PINCH_POSES` is in reach of this hand.
    """
    if not pen_radius > 0:
        raise ValueError(f"pen_radius must be positive [m], got {pen_radius}")
    s = person.hand_scale
    wide = dataclasses.replace(person, pad_contact=2.0 * pen_radius + PEN_PAD_GAP * s)
    for cmc, flexion, dip in PEN_PINCH_POSES:
        try:
            return ReachPinchLift(
                wide, timings, pinch_force=pinch_force, thumb=(cmc, flexion), dip=dip
            )
        except ValueError:  # out of this hand's reach: the next pose
            continue
    raise PersonCannotError(
        f"person {person.person_id!r} cannot pinch the pen: no pinch of {PEN_PINCH_POSES} "
        "(thumb CMC, thumb flexion, index DIP [rad]) is within their reach and range of motion"
    )


def skill_operator(person: PersonParams, pen_radius: float, skill: str) -> SkillOperator:
    """The scripted operator of a skill with the pen: the pen's pinch-lift with
    :data:`~ias_gym.glove.skills.SKILL_TIMINGS`, then ``skill`` in ``person``'s style.

    Args:
        person: the operator's hand (and, by its id, their style).
        pen_radius: the pen's radius [m].
        skill: one of :data:`~ias_gym.glove.skills.SKILLS`.

    Raises:
        InputError: unknown ``skill``.
        ValueError: as :func:`pen_operator`.
    """
    base = pen_operator(person, pen_radius, SKILL_TIMINGS, SKILL_PINCH_FORCE)
    return SkillOperator(base, skill)


#: The simulated persons: in the loop (:class:`~ias_gym.glove.closed_loop.ClosedLoopOperator`)
#: or the open-loop script of the plan alone.
OPERATORS: tuple[str, ...] = ("closed_loop", "script")


class ScriptedOperator(Protocol):
    """A script Θ(t) [rad] with phase times (:class:`ReachPinchLift`, :class:`SkillOperator`)."""

    @property
    def timings(self) -> ReachPinchLiftTimings: ...

    def __call__(self, t: float) -> FloatArray: ...


class FromPreShape:
    """An operator started later: ``Θ(t) = operator(t + start)`` [rad], t [s].

    The episodes of ``IAS-GloveGrasp-v0`` begin when the scripted reach has pre-shaped the
    hand (thumb under the pen, index above it): in the glove's planar hand the thumb's
    opposition swing passes through the place of the pinch, so a pen already lying there
    would be struck (see HUMAN_HAND.md).

    Args:
        operator: the script to run.
        start: where in it the episode begins [s] (default: the end of its reach).
    """

    def __init__(self, operator: ScriptedOperator, start: float | None = None) -> None:
        self.operator = operator
        self.start = operator.timings.reach if start is None else float(start)

    def __call__(self, t: float) -> FloatArray:
        """Intended joint angles Θ ``(10,)`` [rad] at episode time ``t`` [s]."""
        return self.operator(t + self.start)

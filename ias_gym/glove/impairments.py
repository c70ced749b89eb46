"""Impaired glove operators: what goes wrong between a person's intent and the hand.

Each impairment family changes one link of the glove chain of ``IAS-GloveGrasp-v0`` (intent
Θ(t) -> glove readings Ψ -> calibration Θ = f(Ψ) -> the hand's joint targets); a spec
(:mod:`ias_gym.glove.impairment_spec`: ``NAME[:KEY=VALUE,...]``, ``A+B``, ``sampled``)
names the families and their parameters, with the ranges they come from:

=======================  ===========================================================
family                   what
=======================  ===========================================================
``tremor``               a pathological tremor of ``hz`` on the wrist and the
                         pinching fingers (:class:`TremorOperator`)
``weak_grip``            the operator closes index, thumb or both less than the pinch
                         needs (:class:`WeakGripOperator`): too small a squeeze
``lag``                  the glove's readings arrive late (:class:`LaggedGlove`)
``biased_calibration``   the calibration ANN's output is offset on the pinching
                         joints of index, thumb or both (:func:`biased_calibration`)
``hand_size``            the operator runs the stock pinch (planned for a nominal
                         hand) with a hand of this scale (:func:`resized_person`),
                         judged against the same hand's own plan
                         (:func:`reference_kwargs`)
``stops``                the operator performs the first share ``at`` of the skill's
                         own motion and then holds still (:class:`StopsOperator`)
=======================  ===========================================================

Pure numpy on the glove layer's types (no MuJoCo): the env (:mod:`ias_gym.envs.glove_assist`) puts
them together.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from collections import deque
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ias_gym.errors import InputError
from ias_gym.glove.calibration import Calibration
from ias_gym.glove.device import (
    GloveDevice,
    GloveReading,
    GloveWrapper,
    ReachPinchLiftTimings,
    min_jerk,
)
from ias_gym.glove.hand import (
    N_JOINTS,
    NOMINAL_INDEX_LENGTHS,
    NOMINAL_THUMB_BASE,
    NOMINAL_THUMB_LENGTHS,
    PersonParams,
    joint_index,
)
from ias_gym.glove.impairment_spec import (
    FAMILIES,
    NONE,
    STRENGTH_KEY,
    Impairment,
    parse_impairment,
)
from ias_gym.glove.operator import ScriptedOperator
from ias_gym.glove.skills import SkillOperator

FloatArray = NDArray[np.float64]

__all__ = ["Impairment", "parse_impairment"]

#: The impairment families, ``"none"`` first.
IMPAIRMENTS: tuple[str, ...] = (NONE, *FAMILIES)
#: Each family's default size (its :data:`~ias_gym.glove.impairment_spec.STRENGTH_KEY`).
DEFAULT_STRENGTHS: dict[str, float] = {
    NONE: 0.0,
    **{name: float(keys[STRENGTH_KEY[name]].default) for name, keys in FAMILIES.items()},
}
#: Joints that tremor: the wrist and the pinching fingers (as the persons' own physiological
#: tremor of :mod:`ias_gym.glove.skills`, but tens of times stronger).
TREMOR_JOINTS: tuple[str, ...] = (
    "wrist_flexion",
    "wrist_deviation",
    "wrist_pronation",
    "index_mcp",
    "index_pip",
    "thumb_cmc",
    "thumb_flexion",
)
#: Joints whose flexion closes the pinch on the pen, and how much of an opening each takes.
PINCH_JOINTS: dict[str, float] = {"index_mcp": 1.0, "index_pip": 0.5, "thumb_flexion": 1.0}
#: Band of a pathological tremor [Hz] (parkinsonian 4-6 Hz, essential 4-12 Hz: the ``tremor``
#: family's ``hz`` range).
TREMOR_BAND = (4.0, 12.0)
#: Each finger's pinch joints (``fingers=index|thumb``; ``both`` is all of them).
FINGER_JOINTS: dict[str, tuple[str, ...]] = {
    "index": ("index_mcp", "index_pip"),
    "thumb": ("thumb_flexion",),
}


def pinch_direction(fingers: str = "both") -> FloatArray:
    """``(10,)`` the joint direction that closes the pinch (:data:`PINCH_JOINTS`) [-], of
    ``fingers`` (``index``, ``thumb`` or ``both``)."""
    out = np.zeros(N_JOINTS)
    for name, share in PINCH_JOINTS.items():
        if fingers == "both" or name in FINGER_JOINTS[fingers]:
            out[joint_index(name)] = share
    return out


def check_hand_scale(value: float, what: str) -> float:
    """``value`` if it is a hand scale in (0, 2] [-], else an :class:`InputError` naming
    ``what``."""
    if not 0.0 < value <= 2.0:
        raise InputError(f"{what} must be a hand scale in (0, 2], got {value}")
    return value


def reference_kwargs(impairment: Impairment) -> dict[str, Any]:
    """Env kwargs of the unimpaired session an impaired one is judged against: the same
    person without the impairment. For ``hand_size`` that is the same resized hand with an
    operator planning for it (``hand_scale``), so that the plan is the only difference: a
    hand of another size also moves the pen on another lever (the wrist's rotation is the
    same, the pen's centre moves with its distance from the wrist), which no offset of the
    joint targets undoes (measured: docs/assistance.md).
    """
    size = impairment.family("hand_size")
    return {} if size is None else {"hand_scale": size.number("scale")}


def session_rng(tag: str, person_id: str, seed: int | str) -> np.random.Generator:
    """A random stream of ``tag`` for one person and seed (or name), the same on any machine
    (sha256, not Python's salted ``hash()``)."""
    digest = hashlib.sha256(f"{tag}:{person_id}".encode()).digest()
    extra = (
        seed
        if isinstance(seed, int)
        else int.from_bytes(hashlib.sha256(seed.encode()).digest()[:8], "little")
    )
    return np.random.default_rng([int.from_bytes(digest[:8], "little"), extra])


#: The tremor sets in over this time from the episode's start [s] (one period at 10 Hz; a
#: minimum-jerk envelope). The episode starts with the hand at the operator's first pose
#: next to the pen; a tremor at full amplitude from there put the thumb into the pen at the
#: reset (measured on one person, lift_hold: the pen pushed 1.2 mm in the first 10 ms step,
#: and off its support by 0.1 s), which is the reset's overlap, not the tremor.
TREMOR_ONSET = 0.1


class TremorOperator:
    """A script with a tremor: ``Θ(t) + e(t) A sin(2 pi f t + phi_j)`` on
    :data:`TREMOR_JOINTS`, ``e`` rising from 0 to 1 over :data:`TREMOR_ONSET` from the
    episode's start (script time ``timings.reach``).

    Args:
        operator: the script Θ(t) [rad], t [s].
        amplitude: ``A`` [rad].
        hz: the tremor's frequency ``f`` [Hz].
        person_id, seed: draw the phases ``phi_j``, reproducibly.
    """

    def __init__(
        self, operator: ScriptedOperator, amplitude: float, hz: float, person_id: str, seed: int
    ) -> None:
        self.operator = operator
        self.amplitude = float(amplitude)
        #: The tremor's frequency [Hz].
        self.hz = float(hz)
        rng = session_rng("tremor", person_id, seed)
        self._idx = np.array([joint_index(j) for j in TREMOR_JOINTS])
        self._phase = rng.uniform(0.0, 2.0 * math.pi, size=len(TREMOR_JOINTS))

    @property
    def timings(self) -> ReachPinchLiftTimings:
        """The wrapped script's phase times."""
        return self.operator.timings

    def __call__(self, t: float) -> FloatArray:
        """Θ(t) [rad] with the tremor."""
        out = np.array(self.operator(t), dtype=np.float64)
        onset = min_jerk((t - self.timings.reach) / TREMOR_ONSET)
        out[self._idx] += onset * self.amplitude * np.sin(2.0 * math.pi * self.hz * t + self._phase)
        return out


class WeakGripOperator:
    """A script that closes the pinch less: ``Θ(t) - w(t) opening d`` with d the pinch's
    closing direction (:func:`pinch_direction`) and ``w`` rising with the close phase
    (minimum jerk from ``timings.reach`` to ``timings.close``), so the fingers still meet
    the pen but squeeze it less.

    A squeeze along the direction in which the operator's pinch closes for a thinner pen
    (its inverse kinematics: index MCP up, PIP down) was tried first: it moves the index pad
    along the pen's surface rather than into it, and the pen fell out at an unchanged force.

    Args:
        operator: the script Θ(t) [rad].
        opening: how much less the pinch closes [rad] on index MCP and thumb flexion.
        fingers: whose pinch is weak: ``index``, ``thumb`` or ``both``.
    """

    def __init__(self, operator: ScriptedOperator, opening: float, fingers: str = "both") -> None:
        self.operator = operator
        self.opening = float(opening)
        self._d = pinch_direction(fingers)

    @property
    def timings(self) -> ReachPinchLiftTimings:
        """The wrapped script's phase times."""
        return self.operator.timings

    def __call__(self, t: float) -> FloatArray:
        """Θ(t) [rad] with the weaker pinch."""
        t0, t1 = self.timings.reach, self.timings.close
        w = min_jerk((t - t0) / (t1 - t0))
        return np.asarray(self.operator(t), dtype=np.float64) - w * self.opening * self._d


class StopsOperator:
    """A skill's script whose own motion stops: the operator performs the first share ``at``
    of the skill's motion (:meth:`~ias_gym.glove.skills.SkillOperator.offsets`, from its
    start for ``motion_time``) and then holds the pose it reached; the pinch-lift and the
    person's own physiological tremor go on ("the operator only gives the goal"). A person in
    the loop (:class:`~ias_gym.glove.closed_loop.ClosedLoopOperator`) still means the whole
    skill, keeps gripping by touch, and from :attr:`holds_still_from` on no longer corrects
    the pen's pose by sight: they hold still and leave the rest to the system. ``at=1`` is
    the unimpaired operator.

    Args:
        operator: the skill's script.
        at: the share of the skill's own motion performed [0, 1].
    """

    def __init__(self, operator: SkillOperator, at: float) -> None:
        self.operator = operator
        self.at = float(at)
        #: Script time at which the operator stops [s].
        self.stop_time = operator.skill_start + self.at * operator.motion_time
        #: Script time from which a person in the loop no longer corrects by sight [s]
        #: (inf: a motion done to its end).
        self.holds_still_from = self.stop_time if self.at < 1.0 else math.inf

    @property
    def timings(self) -> ReachPinchLiftTimings:
        """The wrapped script's phase times."""
        return self.operator.timings

    def __call__(self, t: float) -> FloatArray:
        """Θ(t) [rad], the skill's offsets held from :attr:`stop_time` on."""
        op = self.operator
        offsets = op.offsets(min(t, self.stop_time))
        return np.asarray(op.base(t) + offsets + op.tremor(t), dtype=np.float64)


class LaggedGlove(GloveWrapper):
    """A glove whose readings arrive ``lag`` late: each read returns the sample read
    ``round(lag * rate)`` reads before (the first sample until then). The force display is
    not delayed.

    Args:
        inner: the glove.
        lag_steps: the delay in reads (at 100 Hz, 10 reads = 100 ms).
    """

    def __init__(self, inner: GloveDevice, lag_steps: int) -> None:
        if lag_steps < 0:
            raise ValueError(f"lag_steps must be >= 0, got {lag_steps}")
        super().__init__(inner)
        self.lag_steps = int(lag_steps)
        self._buffer: deque[GloveReading] = deque(maxlen=self.lag_steps + 1)

    def read(self) -> GloveReading:
        """The reading of ``lag_steps`` reads ago (the first one while the buffer fills)."""
        self._buffer.append(self.inner.read())
        return self._buffer[0]


class PeekGlove(GloveWrapper):
    """A glove read one sample ahead: :meth:`read` returns the sample :attr:`upcoming`
    announced and reads the next. The assistant sits between the glove and the hand: it
    sees the reading the hand is about to get. A scripted operator does not react to the
    force display, so reading ahead changes nothing of the session; a person in the loop
    makes each command one read earlier than the hand gets it, from what they perceived up
    to then (within their own visual and tactile delays).

    Args:
        inner: the glove.
    """

    def __init__(self, inner: GloveDevice) -> None:
        super().__init__(inner)
        self._next: GloveReading | None = None
        #: The reading :meth:`read` returned last (``None`` before the first).
        self.last_reading: GloveReading | None = None

    @property
    def upcoming(self) -> GloveReading:
        """The reading the next :meth:`read` returns."""
        if self._next is None:
            self._next = self.inner.read()
        return self._next

    def read(self) -> GloveReading:
        """The announced reading; the next one is read now."""
        out = self.upcoming
        self._next = self.inner.read()
        self.last_reading = out
        return out


def calibration_bias(offset: float, fingers: str = "both") -> FloatArray:
    """``(10,)`` the output offset [rad] of :func:`biased_calibration`: ``-offset`` on the
    pinch's closing joints of ``fingers`` (:data:`PINCH_JOINTS`, index PIP half), 0
    elsewhere."""
    return -float(offset) * pinch_direction(fingers)


def biased_calibration(
    calibration: Calibration, offset: float, fingers: str = "both"
) -> Calibration:
    """The calibration with its output offset on the pinching joints: every group's
    ``y_mean`` (the ANN's output shift) moved by :func:`calibration_bias` ``(offset)``, so
    ``predict`` returns Θ + bias for every reading (an ANN that learned the pinch poses
    with a constant error, e.g. from a glove that sat differently when calibrated).

    Args:
        calibration: the person's calibration.
        offset: [rad], > 0 opens the pinch.
        fingers: whose joints: ``index``, ``thumb`` or ``both``.

    Returns:
        A new :class:`Calibration` (the input is unchanged).
    """
    bias = calibration_bias(offset, fingers)
    groups = []
    for g in calibration.groups:
        shift = np.array([bias[joint_index(j)] for j in g.outputs])
        groups.append(dataclasses.replace(g, y_mean=np.asarray(g.y_mean) + shift))
    return Calibration(tuple(groups))


def stock_person(person: PersonParams) -> PersonParams:
    """``person`` with the nominal hand geometry (scale 1): whose pinch the stock script
    plans. The style (the id) and the glove fit stay the person's."""
    return dataclasses.replace(
        person,
        hand_scale=1.0,
        index_lengths=NOMINAL_INDEX_LENGTHS,
        thumb_lengths=NOMINAL_THUMB_LENGTHS,
        thumb_base=NOMINAL_THUMB_BASE,
        finger_thickness=0.009,
        pad_contact=0.006,
    )


#: Added to a resized person's seed, so its calibration is cached apart from the original's
#: (the cache names profiles by id and seed).
RESIZED_SEED_OFFSET = 7919


def resized_person(person: PersonParams, scale: float) -> PersonParams:
    """``person`` with a hand of overall scale ``scale``: segment lengths, thumb base,
    finger thickness and pad size of the nominal hand times ``scale`` (the person's own
    proportions, glove fit and style kept), and another seed (its own calibration).

    Args:
        person: the person.
        scale: hand scale [-] (the sampled persons span 0.85-1.15).
    """
    k = scale / person.hand_scale
    return dataclasses.replace(
        person,
        seed=person.seed + RESIZED_SEED_OFFSET,
        hand_scale=float(scale),
        index_lengths=tuple(float(v * k) for v in person.index_lengths),  # type: ignore[arg-type]
        thumb_lengths=tuple(float(v * k) for v in person.thumb_lengths),  # type: ignore[arg-type]
        thumb_base=(person.thumb_base[0] * k, person.thumb_base[1] * k),
        finger_thickness=person.finger_thickness * k,
        pad_contact=person.pad_contact * k,
    )

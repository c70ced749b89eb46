"""Object-level skills a (simulated) person performs with the pinched pen through the glove.

After the reach-pinch-lift of :class:`~ias_gym.glove.device.ReachPinchLift` the
scripted operator performs one of :data:`SKILLS` with the held pen, so that a session
demonstrates a skill a robot hand holding the pen can repeat as an object motion (small
rotations and translations of the held pen, which the robot scales into its workspace).

Which joints move the pinched pen how (measured in ``IAS-GloveGrasp-v0`` on one typical person, a
sine of the joint's target after the lift, period 2 s; ranges of the pen's pose over the
motion, paper frame: x the pen's axis, y up, yaw = the see-saw tilt of sec. 4.3):

==========================  ==============================================================
joint (amplitude)           pen motion
==========================  ==============================================================
wrist_pronation (0.12 rad)  yaw 12 deg (the see-saw tilt), x 17 mm; 0.3 rad drops the pen
wrist_deviation (0.15 rad)  pitch 17 deg (a turn about the vertical), x 34 mm
wrist_flexion (0.2 rad)     height 49 mm, roll 36 deg (the pen rolls between the pads)
index_mcp - thumb_flexion   roll 39 deg (about the pen's own axis), little translation
index_mcp + thumb_flexion   roll 76 deg, height 12 mm
==========================  ==============================================================

The glove hand is planar (index and thumb flex in one plane across the pen, see
HUMAN_HAND.md): its fingers roll the pen about its own axis and move it across, but cannot
tilt its axis. The see-saw and the tilts therefore use the wrist's pronation, one of the
glove's 10 measured joints (the wrist gimbal's potentiometers, paper 2.3): no tracker of the
forearm is needed. The lift and the place use the wrist's extension, as the lift of
ReachPinchLift does.

The skills (:data:`SKILLS`, one line each in :data:`SKILL_DESCRIPTIONS`), all starting
from the lifted pinch at :func:`skill_start_time`: ``lift_hold`` (hold still),
``seesaw_slow`` and ``seesaw_fast`` (the pen's axis tilts up and down), ``tilt_left`` and
``tilt_right`` (tilt and hold; left: the operator's left end of the pen, paper -x, goes
down, so yaw > 0), ``lift_place`` (lower the pen back to its start, still pinched).

Each person performs them in their own way (:class:`SkillStyle`, drawn from the population
of :mod:`ias_gym.glove.population`, deterministic in the person id): amplitude and speed
factors, a delay before the skill, a physiological tremor (8-12 Hz, a few mrad) on the
wrist and the pinching fingers, the delays of their corrections and a grip margin.
Pure numpy (the glove layer).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from ias_gym.errors import InputError
from ias_gym.glove.device import ReachPinchLift, ReachPinchLiftTimings, min_jerk
from ias_gym.glove.hand import N_JOINTS, PersonParams, joint_index
from ias_gym.glove.population import PersonStream

FloatArray = NDArray[np.float64]

#: The skills, in a fixed order.
SKILLS: tuple[str, ...] = (
    "lift_hold",
    "seesaw_slow",
    "seesaw_fast",
    "tilt_left",
    "tilt_right",
    "lift_place",
)
#: One line per skill: the object motion after the pinch-lift.
SKILL_DESCRIPTIONS: dict[str, str] = {
    "lift_hold": "lift the pen and hold it still",
    "seesaw_slow": "see-saw: tilt the pen's axis up and down once, slowly (period ~1.8 s)",
    "seesaw_fast": "see-saw: tilt the pen's axis up and down twice, fast (period ~0.75 s)",
    "tilt_left": "tilt the pen's left end (paper -x) down by ~10 deg and hold",
    "tilt_right": "tilt the pen's right end (paper +x) down by ~10 deg and hold",
    "lift_place": "lift the pen, then lower it back to its start on the support, still pinched",
}

#: Phase times of the pinch-lift before a skill [s] (script time, ReachPinchLift's): the
#: default's close, a shorter hold and a faster lift, so that the skill fits the registered
#: 4 s episode (400 steps) that starts at the end of the reach (1.3 s).
SKILL_TIMINGS = ReachPinchLiftTimings(rest=0.3, reach=1.3, close=2.0, hold=2.3, lift=3.0)
#: The pinch force of a skill's pinch-lift [N] (ReachPinchLift's ``pinch_force``, the
#: default's is 2 N): a firmer pinch for manipulating the pen than for lifting it.
SKILL_PINCH_FORCE = 4.0
#: Nominal pronation amplitudes [rad] of the see-saws and the tilts (measured above: the pen
#: tilts by 0.8-0.9 of the wrist's pronation; 0.3 rad as a sine drops it).
SEESAW_SLOW_AMPLITUDE = 0.16
SEESAW_FAST_AMPLITUDE = 0.13
TILT_AMPLITUDE = 0.18
#: Nominal periods [s] and cycles of the see-saws; time [s] of a tilt and of the place.
SEESAW_SLOW_PERIOD = 1.8
SEESAW_FAST_PERIOD = 0.75
SEESAW_FAST_CYCLES = 2
TILT_TIME = 0.8
PLACE_TIME = 1.0
#: Share of the lift's wrist extension undone by ``lift_place`` (-): a little more than the
#: lift, since the hand sags less on the way down; the pen ends within -1.3..+2.7 mm of
#: its start (measured on five persons; 1.0 left it up to 5.4 mm above).
PLACE_SHARE = 1.1


#: The height above its start a person lifts the pen to [m] (the glove world's success needs
#: 3 cm): the object goal of every lift.
LIFT_GOAL = 0.04
#: The pinched pen's tilt per wrist pronation [-]: it turns with the hand, a little less
#: (measured 0.83-1.0 on unimpaired persons; supination raises its +x end).
TILT_PER_PRONATION = 0.85


def skill_object_target(
    skill: str | None, t: float, style: SkillStyle | None = None
) -> tuple[float, float]:
    """The intended object motion of ``skill`` at episode time ``t`` [s] as a person with
    ``style`` means to do it (None: the nominal person, amplitude and speed 1, no delay): the
    pen's height above its start [m] and its tilt (the paper's yaw; +x end up is positive)
    [rad].

    The pinch-lift before every skill raises the pen to :data:`LIFT_GOAL` (minimum jerk over
    the lift of :data:`SKILL_TIMINGS`); the see-saws and tilts then tilt it by
    :data:`TILT_PER_PRONATION` x their pronation; ``lift_place`` lowers it back to 0. With
    ``skill=None`` only the pinch-lift.

    Raises:
        InputError: an unknown skill.
    """
    if skill is not None:
        check_skill(skill)
    timings = SKILL_TIMINGS
    script_t = t + timings.reach  # the episodes start at the end of the reach
    rise = LIFT_GOAL * min_jerk((script_t - timings.hold) / (timings.lift - timings.hold))
    a, v, delay = (1.0, 1.0, 0.0) if style is None else (style.amplitude, style.speed, style.delay)
    u = script_t - timings.lift - delay  # the skill starts after the lift and the delay
    if skill is None or u <= 0.0:
        return rise, 0.0
    tilt = 0.0
    if skill == "seesaw_slow":
        pron = a * SEESAW_SLOW_AMPLITUDE * _seesaw(u, SEESAW_SLOW_PERIOD / v, 1)
        tilt = -TILT_PER_PRONATION * pron
    elif skill == "seesaw_fast":
        pron = a * SEESAW_FAST_AMPLITUDE * _seesaw(u, SEESAW_FAST_PERIOD / v, SEESAW_FAST_CYCLES)
        tilt = -TILT_PER_PRONATION * pron
    elif skill in ("tilt_left", "tilt_right"):
        sign = 1.0 if skill == "tilt_left" else -1.0
        tilt = sign * TILT_PER_PRONATION * a * TILT_AMPLITUDE * min_jerk(u * v / TILT_TIME)
    elif skill == "lift_place":
        rise = LIFT_GOAL * (1.0 - min_jerk(u * v / PLACE_TIME))
    return rise, tilt


def check_skill(name: object, what: str = "skill") -> str:
    """Return ``name`` if it is one of :data:`SKILLS`, else raise.

    Args:
        name: the skill's name.
        what: how the caller calls it in messages (``"skill"``, ``"--skill"``).

    Returns:
        ``name`` unchanged.

    Raises:
        InputError: not a known skill; the message lists the valid ones.
    """
    if not isinstance(name, str) or name not in SKILLS:
        raise InputError(f"{what} {name!r} is not a glove skill; choose one of {', '.join(SKILLS)}")
    return name


@dataclass(frozen=True)
class SkillStyle:
    """How one person moves (drawn by :meth:`sample` from the person id).

    Every number comes from its distribution in
    :data:`ias_gym.glove.population.PARAMETERS` (named in brackets; ``docs/population.md``
    gives the distributions and their sources).

    Attributes:
        person_id: whose style.
        amplitude: factor on the skills' amplitudes (-) (``amplitude``).
        speed: factor on the skills' speed (-): periods and times / speed (``speed``).
        delay: pause between the lift and the skill's own motion [s] (``start_delay``).
        tremor: amplitude of the tremor on each tremoring joint [rad] (``tremor_amplitude``).
        tremor_hz: ``(2,)`` its two frequencies [Hz] (``tremor_hz``).
        tremor_phase: ``(n_joints, 2)`` phases of both per joint [rad].
        visual_delay: from seeing an error to correcting it [s] (``visual_delay``).
        tactile_delay: from feeling a slip to gripping harder [s] (``tactile_delay``).
        grip_margin: grip force above the least that holds the object, over that least
            force (-) (``grip_margin``).
    """

    person_id: str
    amplitude: float
    speed: float
    delay: float
    tremor: float
    tremor_hz: tuple[float, float]
    tremor_phase: tuple[tuple[float, float], ...]
    visual_delay: float = 0.12
    tactile_delay: float = 0.07
    grip_margin: float = 0.25

    @classmethod
    def sample(cls, person_id: str) -> SkillStyle:
        """The style of ``person_id``, reproducibly (the same id gives the same style).

        Raises:
            InputError: ``person_id`` is not a valid id (:func:`~ias_gym.glove.ids.check_id`).
        """
        # "style" keeps this stream apart from the hand's (PersonParams.sample).
        stream = PersonStream(person_id, "style")
        phase = stream.rng.uniform(0.0, 2.0 * math.pi, size=(len(TREMOR_JOINTS), 2))
        hz = stream.draws("tremor_hz", 2)
        return cls(
            person_id=person_id,
            amplitude=stream.draw("amplitude"),
            speed=stream.draw("speed"),
            delay=stream.draw("start_delay"),
            tremor=stream.draw("tremor_amplitude"),
            tremor_hz=(hz[0], hz[1]),
            tremor_phase=tuple((float(a), float(b)) for a, b in phase),
            visual_delay=stream.draw("visual_delay"),
            tactile_delay=stream.draw("tactile_delay"),
            grip_margin=stream.draw("grip_margin"),
        )


def person_parameters(person_id: str) -> dict[str, float]:
    """Every scalar parameter of a person's hand (:class:`~ias_gym.glove.hand.PersonParams`)
    and style (:class:`SkillStyle`), by name, plus ``index_length`` (the finger's three
    phalanges) [m]: for tables and plots of a population.

    Raises:
        InputError: an invalid id.
    """
    return parameters_of(PersonParams.sample(person_id), SkillStyle.sample(person_id))


def parameters_of(person: PersonParams, style: SkillStyle) -> dict[str, float]:
    """:func:`person_parameters` of a given hand and style (e.g. a glove env's, which a
    recording stores with the session)."""
    hand = person.to_dict()
    values = {**hand, **asdict(style)}
    out = {
        key: float(value)
        for key, value in values.items()
        if isinstance(value, int | float) and not isinstance(value, bool) and key != "seed"
    }
    out["index_length"] = float(sum(hand["index_lengths"]))
    return out


#: Joints with tremor: the wrist and the pinching fingers (the others rest curled).
TREMOR_JOINTS: tuple[str, ...] = (
    "wrist_flexion",
    "wrist_deviation",
    "wrist_pronation",
    "index_mcp",
    "index_pip",
    "thumb_cmc",
    "thumb_flexion",
)


def _seesaw(u: float, period: float, cycles: float) -> float:
    """A see-saw of unit amplitude at time ``u`` [s] after its start: a sine whose first and
    last quarter periods fade in and out (minimum jerk), so the wrist starts and stops at
    rest; 0 before and after."""
    length = period * cycles
    if u <= 0.0 or u >= length:
        return 0.0
    ramp = 0.25 * period
    envelope = min(min_jerk(u / ramp), min_jerk((length - u) / ramp))
    return envelope * math.sin(2.0 * math.pi * u / period)


class SkillOperator:
    """The scripted operator of a skill: a pinch-lift, then the skill, with a person's style.

    Θ(t) = ``base(t)`` (the pen's pinch-lift with :data:`SKILL_TIMINGS`) + the skill's joint
    offsets from :attr:`skill_start` on + the person's tremor (all times script time [s]).

    Args:
        base: the person's pinch-lift (:func:`~ias_gym.glove.operator.pen_operator` with
            :data:`SKILL_TIMINGS`).
        skill: one of :data:`SKILLS`.
        style: the person's way of performing it (default: ``SkillStyle.sample`` of
            ``base.person``'s id).

    Raises:
        InputError: ``skill`` is not one of :data:`SKILLS`.
    """

    def __init__(self, base: ReachPinchLift, skill: str, style: SkillStyle | None = None) -> None:
        self.base = base
        self.skill = check_skill(skill)
        self.style = style if style is not None else SkillStyle.sample(base.person.person_id)
        self.timings = base.timings
        #: Script time [s] where the skill's own motion begins (after lift and delay).
        self.skill_start = base.timings.lift + self.style.delay
        self._pron = joint_index("wrist_pronation")
        self._wf = joint_index("wrist_flexion")
        self._tremor_idx = np.array([joint_index(j) for j in TREMOR_JOINTS])
        self._tremor_phase = np.array(self.style.tremor_phase)
        self._lift = float(base.poses["lifted"][self._wf] - base.poses["pinch"][self._wf])

    @property
    def duration(self) -> float:
        """Script time [s] at which the skill's motion has ended (it holds after)."""
        return self.skill_start + self.motion_time

    @property
    def motion_time(self) -> float:
        """Length of the skill's own motion [s] at this person's speed."""
        return skill_motion_time(self.skill, self.style.speed)

    def offsets(self, t: float) -> FloatArray:
        """The skill's joint offsets ``(10,)`` [rad] at script time ``t`` [s] (no tremor)."""
        out = np.zeros(N_JOINTS)
        u = t - self.skill_start
        if u <= 0.0 or self.skill == "lift_hold":
            return out
        a, v = self.style.amplitude, self.style.speed
        if self.skill == "seesaw_slow":
            out[self._pron] = a * SEESAW_SLOW_AMPLITUDE * _seesaw(u, SEESAW_SLOW_PERIOD / v, 1)
        elif self.skill == "seesaw_fast":
            out[self._pron] = (
                a * SEESAW_FAST_AMPLITUDE * _seesaw(u, SEESAW_FAST_PERIOD / v, SEESAW_FAST_CYCLES)
            )
        elif self.skill in ("tilt_left", "tilt_right"):
            # Supination (-) turns the pen's left end (paper -x) down (yaw > 0), measured.
            sign = -1.0 if self.skill == "tilt_left" else 1.0
            out[self._pron] = sign * a * TILT_AMPLITUDE * min_jerk(u * v / TILT_TIME)
        else:  # lift_place: undo the lift's wrist extension (the person's own lift)
            out[self._wf] = -PLACE_SHARE * self._lift * min_jerk(u * v / PLACE_TIME)
        return out

    def tremor(self, t: float) -> FloatArray:
        """The person's tremor ``(10,)`` [rad] at script time ``t`` [s]."""
        out = np.zeros(N_JOINTS)
        hz = np.array(self.style.tremor_hz)
        waves = np.sin(2.0 * math.pi * hz[None, :] * t + self._tremor_phase)
        out[self._tremor_idx] = 0.5 * self.style.tremor * waves.sum(axis=1)
        return out

    def __call__(self, t: float) -> FloatArray:
        """Intended joint angles Θ(t) ``(10,)`` [rad] at script time ``t`` [s]."""
        return self.base(t) + self.offsets(t) + self.tremor(t)


def skill_motion_time(skill_name: str, speed: float) -> float:
    """Length [s] of ``skill_name``'s own motion at speed factor ``speed``
    (:attr:`SkillStyle.speed`); 0 for ``lift_hold``.

    Raises:
        InputError: unknown skill.
    """
    check_skill(skill_name)
    return {
        "lift_hold": 0.0,
        "seesaw_slow": SEESAW_SLOW_PERIOD / speed,
        "seesaw_fast": SEESAW_FAST_PERIOD * SEESAW_FAST_CYCLES / speed,
        "tilt_left": TILT_TIME / speed,
        "tilt_right": TILT_TIME / speed,
        "lift_place": PLACE_TIME / speed,
    }[skill_name]


def skill_start_time(skill_name: str, person: PersonParams | str) -> float:
    """Episode time [s] at which ``skill_name``'s own motion begins for ``person``.

    ``IAS-GloveGrasp-v0`` episodes start at the end of the reach (script time
    ``SKILL_TIMINGS.reach``); the skill starts at the end of the lift plus the person's
    delay (:class:`SkillStyle`). Before it, every skill is the same pinch-lift.

    Args:
        skill_name: one of :data:`SKILLS`.
        person: the person or their id.

    Returns:
        The start [s] since the episode's reset.

    Raises:
        InputError: unknown skill or invalid person id.
    """
    check_skill(skill_name)
    person_id = person if isinstance(person, str) else person.person_id
    style = SkillStyle.sample(person_id)
    return SKILL_TIMINGS.lift - SKILL_TIMINGS.reach + style.delay

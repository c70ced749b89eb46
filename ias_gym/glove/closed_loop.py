"""A simulated person in the loop: acts on the pen they see and the force they feel.

The scripted operators (:class:`~ias_gym.glove.device.ReachPinchLift`,
:class:`~ias_gym.glove.skills.SkillOperator`) are a person's *plan*: the minimum-jerk joint
motion that would do the skill if the hand did exactly what the person intends. A real person
closes the loop around it (paper sec. 2.1: the operator sees the virtual world and feels its
contact forces through the force display). :class:`ClosedLoopOperator` runs the plan and adds
two corrections a person makes:

- **Grip** (touch): from the first felt contact on, the person regulates the pinch force they
  feel to their target ``(1 + grip_margin) x F_slip`` (Westling & Johansson 1984: people keep
  their grip a personal margin above the slip force), where ``F_slip = W / (2 mu)`` is the
  least pinch that holds an object of weight W with two pads of friction mu (the person knows
  the pen's weight and feel from handling it). The felt force is estimated from the
  force-display torques on the index joints through the person's own finger kinematics
  (``tau = J^T f``), and it reaches them after their ``tactile_delay``. The pinch they
  command stays between half the plan's and the plan's (:data:`SQUEEZE_RANGE`).
- **Position** (vision): in the holds after the lift, the person compares what they see of the
  pen, delayed by their ``visual_delay``, with what they expected to see: the tilt it had
  after the lift plus what their plan turned it by (a tilt), the lifted height
  (:data:`LIFT_GOAL`) or, after a place, the support. Both
  corrections are integrators whose gain follows the crossover model of human control
  (McRuer & Jex, IEEE Trans. HFE 8(3), 1967): ``gain x delay = CROSSOVER_PHASE``, so a person
  is as fast as their own delay allows with a phase margin of about 60 deg. A delay the person
  does not know of (a glove lag) therefore makes them overshoot: a real impairment.

A person fails in human ways: when they see the pen fall (below its start by
:data:`DROP_SEEN`), they give up and hold still (:attr:`ClosedLoopOperator.failure` says so);
a plan outside their range of motion (:attr:`~ias_gym.glove.hand.PersonParams.joint_limits`)
is clipped to it and reported as the reason (:attr:`~ClosedLoopOperator.infeasible`).

Times: the operator is called with the glove's (episode) time; the plan runs at
``t + start`` (its script time, as :class:`~ias_gym.glove.operator.FromPreShape`). Pure numpy.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Generic, TypeVar

import numpy as np
from numpy.typing import NDArray

from ias_gym.glove.device import ReachPinchLift, WorldView
from ias_gym.glove.hand import (
    INDEX_JOINTS,
    JOINT_NAMES,
    THUMB_FLEXION_SHARES,
    PersonParams,
    index_points,
    joint_index,
    thumb_points,
)
from ias_gym.glove.operator import ScriptedOperator
from ias_gym.glove.sensor_model import index_pinch_angles
from ias_gym.glove.skills import LIFT_GOAL, TILT_PER_PRONATION, SkillOperator, SkillStyle

FloatArray = NDArray[np.float64]
T = TypeVar("T")

#: Phase lag of a person's loop at its crossover frequency [rad] (gain x delay): 0.5 rad leaves
#: a phase margin of 90 - 29 = 61 deg (McRuer & Jex 1967, the crossover model).
CROSSOVER_PHASE = 0.5
#: Where a place puts the pen back [m]: on its support, touching it.
PLACE_GOAL = 0.0
#: The pen's rise per wrist extension the person expects [m/rad] (0.3 rad lift 33-42 mm).
RISE_PER_EXTENSION = 0.12
#: A person sees the pen fall when it is this far below its start [m]; they give up.
DROP_SEEN = 0.01
#: Range of the pinch a person commands, as a share of the plan's [-]: they loosen toward
#: their goal but squeeze no deeper than they planned. In this world the felt squeeze hardly
#: rises with a deeper pinch (the thumb carries the pen from below and the index presses its
#: side: a deeper index flexion pushes the pen off the thumb rather than harder onto it), so
#: a deeper squeeze only tips the pen: measured on development persons, tilt_left held 21 of
#: 30 with the squeeze allowed to 1.5 x the plan's and 26 of 30 with it stopped at the plan.
SQUEEZE_RANGE = (0.5, 1.0)
#: Largest correction a person adds to the plan [rad] (the wrist's and the pinch's).
MAX_CORRECTION = 0.3

_WF = joint_index("wrist_flexion")
_WP = joint_index("wrist_pronation")
_CMC, _TF = joint_index("thumb_cmc"), joint_index("thumb_flexion")
_I1, _I2, _I3 = INDEX_JOINTS


def pen_tilt(quat: NDArray[np.float64]) -> float:
    """The pen axis's tilt above the horizontal [rad] (yaw of the paper frame: its +x end up
    is positive) from its world quaternion (w, x, y, z)."""
    w, x, y, z = (float(v) for v in quat)
    ax = 1.0 - 2.0 * (y * y + z * z)
    az = 2.0 * (x * z - w * y)
    return math.atan2(az, ax)


class _Delayed(Generic[T]):
    """Samples ``(time, value)`` and the latest one at least ``delay`` [s] old."""

    def __init__(self, delay: float) -> None:
        self.delay = float(delay)
        self._queue: deque[tuple[float, T]] = deque()
        self.value: T | None = None

    def push(self, time: float, value: T) -> None:
        self._queue.append((time, value))

    def at(self, now: float) -> T | None:
        while self._queue and self._queue[0][0] <= now - self.delay + 1e-9:
            self.value = self._queue.popleft()[1]
        return self.value


def inner_plan(plan: ScriptedOperator) -> SkillOperator | ReachPinchLift:
    """The skill's plan (or the pinch-lift) inside impairment wrappers, each of which keeps
    the plan it changes as ``operator``.

    Raises:
        TypeError: ``plan`` wraps neither.
    """
    inner: object = plan
    while not isinstance(inner, SkillOperator | ReachPinchLift):
        if not hasattr(inner, "operator"):
            raise TypeError(f"{type(plan).__name__} wraps no SkillOperator or ReachPinchLift")
        inner = inner.operator
    return inner


def _holds_still_from(plan: ScriptedOperator) -> float:
    """The earliest ``holds_still_from`` [s] of ``plan`` and the plans it wraps (inf: none)."""
    out = math.inf
    inner: object = plan
    while inner is not None:
        out = min(out, float(getattr(inner, "holds_still_from", math.inf)))
        inner = getattr(inner, "operator", None)
    return out


class ClosedLoopOperator:
    """A person doing a plan in the loop: grip by touch, position by sight (module docstring).

    Args:
        plan: the person's plan (a skill's :class:`SkillOperator` or a
            :class:`ReachPinchLift`), in script time; or an impaired one
            (:mod:`ias_gym.glove.impairments`: a wrapper that keeps the plan it changes as
            ``operator``): the person moves by the wrapper and judges what they see by the
            plan inside it (:func:`inner_plan`). A plan that stops short
            (:class:`~ias_gym.glove.impairments.StopsOperator`, its ``holds_still_from``)
            ends the person's corrections by sight from then on: they hold still.
        person: their hand (the finger kinematics of the felt force).
        style: how they move (delays, grip margin); default
            ``SkillStyle.sample(person.person_id)``.
        object_weight: the pen's weight [N].
        friction: the pads' friction coefficient on the pen (-).
        start: script time of episode time 0 [s] (default: the end of the plan's reach).

    Raises:
        ValueError: a non-positive weight or friction.
    """

    def __init__(
        self,
        plan: ScriptedOperator,
        person: PersonParams,
        style: SkillStyle | None = None,
        *,
        object_weight: float,
        friction: float,
        start: float | None = None,
    ) -> None:
        if not (object_weight > 0 and friction > 0):
            raise ValueError(
                f"object_weight and friction must be positive, got {object_weight}, {friction}"
            )
        self.plan = plan
        #: The skill's plan (or the pinch-lift) the person judges what they see by.
        self.intent = inner_plan(plan)
        #: Script time [s] from which the person no longer corrects by sight (a plan that
        #: stops; otherwise never).
        self.holds_still_from = _holds_still_from(plan)
        intent = self.intent
        base = intent.base if isinstance(intent, SkillOperator) else intent
        self.skill = intent.skill if isinstance(intent, SkillOperator) else None
        self.person = person
        self.style = style if style is not None else SkillStyle.sample(person.person_id)
        self.timings = plan.timings
        self.start = self.timings.reach if start is None else float(start)
        st = self.style
        #: The pinch force the person aims for [N].
        self.grip_goal = (1.0 + st.grip_margin) * object_weight / (2.0 * friction)
        pinch = base.poses["pinch"]
        thumb, dip = pinch[[_CMC, _TF]], np.array([pinch[_I3]])
        f0 = base.pinch_force
        # How the plan's index angles change per newton of intended pinch [rad/N], on the
        # plan's own hand (the pen's width as its pad gap); a pinch at the edge of the index's
        # reach (a straight PIP) has it on one side only.
        self._squeeze_dir = np.zeros(len(JOINT_NAMES))
        for a, b in ((f0, f0 + 0.5), (f0 - 0.5, f0)):
            lo, hi = (
                index_pinch_angles(thumb[None], dip, np.array([force]), base.person)[0]
                for force in (a, b)
            )
            if np.isfinite(lo).all() and np.isfinite(hi).all():
                self._squeeze_dir[[_I1, _I2]] = (hi - lo) / (b - a)
                break
        self._planned_force = f0
        self._squeeze = f0  # the pinch force the person commands now [N]
        self._grip_gain = CROSSOVER_PHASE / st.tactile_delay  # [1/s]
        self._vision_gain = CROSSOVER_PHASE / st.visual_delay  # [1/s]
        self._felt: _Delayed[FloatArray] = _Delayed(st.tactile_delay)
        self._seen: _Delayed[tuple[FloatArray, float]] = _Delayed(st.visual_delay)
        self._touched = False
        self._correction = np.zeros(len(JOINT_NAMES))
        self._last_t: float | None = None
        self._tilt_reference: float | None = None
        self._frozen: FloatArray | None = None
        self._low, self._high = person.joint_limits
        #: Why the session failed on the person's side (``""``: it did not).
        self.failure = ""
        #: Why this person cannot do the plan as planned (``""``: they can).
        self.infeasible = self._check_reach(base)

    # ------------------------------------------------------------------ perception
    def see(self, view: WorldView) -> None:
        """What the person sees of the pen now (reaches them after ``visual_delay``)."""
        self._seen.push(view.time, (view.pen_position.copy(), pen_tilt(view.pen_quat)))

    def feel(self, time: float, torques: NDArray[np.float64]) -> None:
        """The force display's torques now (felt after ``tactile_delay``)."""
        self._felt.push(time, np.asarray(torques, dtype=np.float64).copy())

    # ------------------------------------------------------------------ the person
    def _check_reach(self, base: ReachPinchLift) -> str:
        for name, pose in base.poses.items():
            out = (pose < self._low - 1e-9) | (pose > self._high + 1e-9)
            if out.any():
                joints = [JOINT_NAMES[i] for i in np.flatnonzero(out)]
                return f"the {name} pose needs {', '.join(joints)} beyond the range of motion"
        return ""

    def felt_force(self, torques: NDArray[np.float64], theta: FloatArray) -> float:
        """The pinch force [N] a person infers from the force display on their index and thumb
        joints: ``tau = J^T f`` solved for the planar force ``f`` of the index pad (the thumb
        pad's is ``-f``) by least squares, J of their own fingers at ``theta``
        (:mod:`ias_gym.glove.hand`). Measured against the contacts' normal force: 10-25 %
        high, as a person's sense of force is no better (a Weber fraction of 5-10 %)."""
        pts = index_points(theta[[_I1, _I2, _I3]], self.person.index_lengths)
        tip = pts[-1]
        thumb = thumb_points(theta[[_CMC, _TF]], self.person.thumb_lengths, self.person.thumb_base)
        ttip = thumb[-1]
        # Rows: the pad's velocity per rate of each joint (planar, i x lever), index then thumb
        # (CMC, and the flexion shared by MCP and IP, which turns clockwise).
        cols = [1j * (tip - pts[j]) for j in range(3)]
        cols.append(1j * (ttip - thumb[0]))
        mcp, ip = THUMB_FLEXION_SHARES
        cols.append(-(mcp * 1j * (ttip - thumb[1]) + ip * 1j * (ttip - thumb[2])))
        jac = np.array([[c.real, c.imag] for c in cols])
        force, *_ = np.linalg.lstsq(jac, torques, rcond=None)
        return float(np.hypot(force[0], force[1]))

    def _goals(self, script_t: float) -> tuple[float | None, float | None]:
        """(height [m], tilt [rad]) the person expects to see at script time ``script_t``;
        None where they do not judge it. In the holds from the lift's end on, the pen should
        keep the tilt it had then, plus what the plan's pronation turned it by
        (:data:`TILT_PER_PRONATION`), at the height :data:`LIFT_GOAL` (after a place:
        :data:`PLACE_GOAL`). During a movement (the lift, the skill's own) the person moves by
        their plan and corrects at its end (Woodworth's two components of an aimed
        movement: the initial impulse, then the corrections)."""
        if script_t < self.timings.lift or self._tilt_reference is None:
            return None, None
        plan = self.intent
        if not isinstance(plan, SkillOperator):
            return LIFT_GOAL, self._tilt_reference
        if plan.skill_start <= script_t < plan.duration:
            return None, None  # the skill's own movement: feedforward, corrected at its end
        tilt = self._tilt_reference - TILT_PER_PRONATION * float(plan.offsets(script_t)[_WP])
        if self.skill == "lift_place" and script_t >= plan.duration:
            return PLACE_GOAL, tilt
        return LIFT_GOAL, tilt

    def __call__(self, t: float) -> FloatArray:
        """Intended joint angles Θ ``(10,)`` [rad] at episode time ``t`` [s]."""
        if self._frozen is not None:
            return self._frozen.copy()
        script_t = t + self.start
        dt = 0.0 if self._last_t is None else max(t - self._last_t, 0.0)
        self._last_t = t
        plan = np.asarray(self.plan(script_t), dtype=np.float64)
        theta = plan + self._correction + (self._squeeze - self._planned_force) * self._squeeze_dir

        torques = self._felt.at(t)
        if torques is not None and dt > 0:
            felt = self.felt_force(torques, theta)
            self._touched = self._touched or felt > 0.2 * self.grip_goal
            if self._touched and script_t >= self.timings.close:
                step = self._grip_gain * dt * (self.grip_goal - felt)
                low, high = (share * self._planned_force for share in SQUEEZE_RANGE)
                self._squeeze = float(np.clip(self._squeeze + step, low, high))

        seen = self._seen.at(t)
        if seen is not None and dt > 0:
            position, tilt = seen
            if position[2] < -DROP_SEEN and script_t > self.timings.hold:
                self.failure = "dropped the pen"
                self._frozen = np.clip(theta, self._low, self._high)
                return self._frozen.copy()
            seen_t = script_t - self.style.visual_delay  # when what they see happened
            if self._tilt_reference is None and seen_t >= self.timings.lift:
                self._tilt_reference = float(tilt)  # the pen as the lift left it
            height_goal, tilt_goal = self._goals(seen_t)
            if script_t >= self.holds_still_from:
                height_goal = tilt_goal = None
            k = self._vision_gain * dt
            if height_goal is not None:
                # Extension (negative flexion) raises the pen.
                self._correction[_WF] -= k * (height_goal - position[2]) / RISE_PER_EXTENSION
            if tilt_goal is not None:
                # Supination (negative pronation) raises the +x end (tilt > 0), measured.
                self._correction[_WP] -= k * (tilt_goal - tilt) / TILT_PER_PRONATION
            np.clip(self._correction, -MAX_CORRECTION, MAX_CORRECTION, out=self._correction)
        return np.clip(theta, self._low, self._high)

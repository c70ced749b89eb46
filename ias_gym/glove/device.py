"""The glove as a device: readings in, feedback torques out (paper 2.1-2.3, Figs. 1-2).

:class:`GloveDevice` is the interface every glove implements (the simulated one here, the CAN
glove of :mod:`ias_gym.hardware` later): :meth:`~GloveDevice.read` returns the 10 readings Ψ
[rad] with a time stamp [s]; :meth:`~GloveDevice.write_feedback` sends the force display's
joint torques [N m] to the glove's actuators; it is a context manager that closes the device.

Actuated joints (our choice, :data:`ACTUATED_JOINTS`): the index finger's three joints and
the thumb's two, 5 actuators. The virtual world's contact forces in precision grasps (the pen,
a pinch) act on the index and thumb pads, so these are the joints whose torques give the
operator the feel of the object; the wrist is the glove's base (an actuator there has nothing
to push against but the forearm) and the other fingers, moving together, take no part in
thumb-index grasps.

:class:`SimulatedGlove` is a glove on a simulated person: a scripted operator (any callable
``t -> Θ`` [s -> rad], :class:`Operator`) gives the intended joint angles, seen through the
person's sensor model (:func:`~ias_gym.glove.sensor_model.sensor_readings`, with noise). Its
clock is simulated: the k-th :meth:`~SimulatedGlove.read` (k = 0, 1, ...) is at
``t = k / rate_hz``. It records the feedback it receives (:attr:`SimulatedGlove.feedback`), and
an operator who perceives (:class:`Perceiver`: a person in the loop) feels it and sees the
virtual world (:meth:`GloveDevice.show`, a :class:`WorldView`).

:class:`ReachPinchLift` is such an operator: reach with a pre-shaped hand, close thumb and
index into a pinch (the pads press with :attr:`ReachPinchLift.pinch_force` [N]), hold, lift by
extending and radially deviating the wrist while holding, then hold still. Phase timings [s]
are in :class:`ReachPinchLiftTimings` (defaults: rest 0-0.3, reach -1.3, close -2.0, hold
-2.5, lift -3.5, hold lifted -4.5); joint motions are minimum-jerk between key poses.
"""

from __future__ import annotations

import abc
import itertools
from dataclasses import dataclass
from types import TracebackType
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ias_gym.glove.hand import (
    INDEX_JOINTS,
    N_JOINTS,
    PersonParams,
    joint_index,
)
from ias_gym.glove.ids import check_id
from ias_gym.glove.profile import DEFAULT_GLOVE_ID
from ias_gym.glove.sensor_model import index_pinch_angles, sensor_readings

#: The glove's actuated joints, in the order of the feedback vector.
ACTUATED_JOINTS: tuple[str, ...] = (
    "index_mcp",
    "index_pip",
    "index_dip",
    "thumb_cmc",
    "thumb_flexion",
)
#: Torque limit of each actuator [N m]; larger commands saturate.
MAX_FEEDBACK_TORQUE = 0.5


@dataclass(frozen=True, eq=False)
class GloveReading:
    """One sample of the glove.

    Attributes:
        psi: ``(10,)`` float64 readings Ψ [rad], order of
            :data:`~ias_gym.glove.hand.SENSOR_NAMES`.
        timestamp: time of the sample [s] (device clock).
    """

    psi: NDArray[np.float64]
    timestamp: float


def check_feedback(torques: ArrayLike, n_actuators: int) -> NDArray[np.float64]:
    """Validate feedback torques [N m] and saturate them at :data:`MAX_FEEDBACK_TORQUE`.

    Raises:
        ValueError: wrong shape, or NaN / inf entries.
    """
    t = np.array(torques, dtype=np.float64)
    if t.shape != (n_actuators,):
        raise ValueError(
            f"feedback torques must have shape ({n_actuators},) for {list(ACTUATED_JOINTS)}, "
            f"got {t.shape}"
        )
    if not np.isfinite(t).all():
        raise ValueError(f"feedback torques must be finite, got {t.tolist()}")
    return np.clip(t, -MAX_FEEDBACK_TORQUE, MAX_FEEDBACK_TORQUE)


@dataclass(frozen=True, eq=False)
class WorldView:
    """What the wearer sees of the virtual world at one instant (its display).

    Attributes:
        time: when [s] (the glove's clock).
        pen_position: ``(3,)`` the pen's centre relative to its start [m], world frame (z up).
        pen_quat: ``(4,)`` the pen's orientation quaternion (w, x, y, z), world frame; the
            pen's axis is its body x.
    """

    time: float
    pen_position: NDArray[np.float64]
    pen_quat: NDArray[np.float64]


class Perceiver(Protocol):
    """An operator who acts on what they perceive (:class:`SimulatedGlove` forwards to it)."""

    def see(self, view: WorldView) -> None:
        """The virtual world as displayed now."""

    def feel(self, time: float, torques: NDArray[np.float64]) -> None:
        """The force display's torques [N m] on :data:`ACTUATED_JOINTS`, applied at ``time``
        [s]."""


class GloveDevice(abc.ABC):
    """A sensor glove with force feedback: read Ψ, write actuator torques, close."""

    glove_id: str

    @abc.abstractmethod
    def read(self) -> GloveReading:
        """The next sample: readings Ψ ``(10,)`` [rad] and its time stamp [s]."""

    @abc.abstractmethod
    def write_feedback(self, torques: ArrayLike) -> None:
        """Send joint torques [N m] for :data:`ACTUATED_JOINTS`, shape ``(n_actuators,)``.

        Raises:
            ValueError: wrong shape or non-finite values (nothing is sent).
        """

    @property
    @abc.abstractmethod
    def n_actuators(self) -> int:
        """Number of actuated joints (length of the feedback vector)."""

    @abc.abstractmethod
    def close(self) -> None:
        """Release the device (idempotent); zero torques first where there are actuators."""

    @property
    def fault(self) -> str | None:
        """Why the device's readings cannot be trusted now (e.g. a watchdog trip), or None.

        A device with a fault keeps its actuators off until :meth:`enable`.
        """
        return None

    def enable(self) -> None:  # noqa: B027 - a no-op unless the device has actuators to arm
        """Arm the actuators and clear a fault (the explicit re-enable after a trip)."""

    def show(self, view: WorldView) -> None:  # noqa: B027 - a real wearer sees the screen
        """Show the wearer the virtual world (``view``). A real glove's wearer looks at the
        display, so nothing goes through the device; a simulated one forwards it to its
        operator."""

    def __enter__(self) -> GloveDevice:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


class Operator(Protocol):
    """A (scripted) human operator: intended joint angles Θ ``(10,)`` [rad] at time t [s]."""

    def __call__(self, t: float) -> NDArray[np.float64]: ...


class GloveWrapper(GloveDevice):
    """A glove that passes everything to ``inner``; subclasses change what they need
    (e.g. :meth:`read`), as Gymnasium's wrappers do for envs.

    Args:
        inner: the glove to wrap.
    """

    def __init__(self, inner: GloveDevice) -> None:
        self.inner = inner
        self.glove_id = inner.glove_id

    def read(self) -> GloveReading:
        """``inner``'s reading."""
        return self.inner.read()

    def write_feedback(self, torques: ArrayLike) -> None:
        """Pass the force display [N m] to ``inner``."""
        self.inner.write_feedback(torques)

    @property
    def n_actuators(self) -> int:
        """``inner``'s number of actuators."""
        return self.inner.n_actuators

    @property
    def fault(self) -> str | None:
        """``inner``'s fault."""
        return self.inner.fault

    def enable(self) -> None:
        """Arm ``inner``."""
        self.inner.enable()

    def show(self, view: WorldView) -> None:
        """Show ``inner``'s wearer the virtual world."""
        self.inner.show(view)

    def close(self) -> None:
        """Close ``inner``."""
        self.inner.close()


class SimulatedGlove(GloveDevice):
    """The glove on a simulated person driven by a scripted operator.

    Args:
        person: the wearer (sensor model parameters).
        operator: intended joint angles Θ(t) [rad], t [s].
        seed: seeds the sensor noise.
        rate_hz: sample rate [Hz]; the k-th read is at t = k / rate_hz.
        glove_id: the glove's id (profiles are checked against it; the rule of
            :func:`~ias_gym.glove.ids.check_id`).
        noise: add sensor noise (False: the noise-free g_person(Θ)).

    Raises:
        ValueError: ``rate_hz`` is not positive.
        InputError: ``glove_id`` is not a valid id.
    """

    def __init__(
        self,
        person: PersonParams,
        operator: Operator,
        seed: int = 0,
        *,
        rate_hz: float = 100.0,
        glove_id: str = DEFAULT_GLOVE_ID,
        noise: bool = True,
    ) -> None:
        if not rate_hz > 0:
            raise ValueError(f"rate_hz must be positive, got {rate_hz}")
        self.person = person
        self.operator = operator
        self.rate_hz = float(rate_hz)
        self.glove_id = check_id(glove_id, "glove_id")
        self._rng = np.random.default_rng(seed) if noise else None
        self._k = 0
        self._last_read_time = 0.0
        self._closed = False
        #: (time of the last read [s], saturated torques [N m]) per write_feedback call.
        self.feedback: list[tuple[float, NDArray[np.float64]]] = []
        #: Θ of the last read [rad] (the simulation's ground truth).
        self.last_theta: NDArray[np.float64] | None = None
        see, feel = getattr(operator, "see", None), getattr(operator, "feel", None)
        self._perceiver: Perceiver | None = (
            operator if callable(see) and callable(feel) else None  # type: ignore[assignment]
        )

    @property
    def n_actuators(self) -> int:
        return len(ACTUATED_JOINTS)

    @property
    def time(self) -> float:
        """Time of the next read [s]."""
        return self._k / self.rate_hz

    @property
    def closed(self) -> bool:
        return self._closed

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError(f"glove {self.glove_id!r} is closed")

    def read(self) -> GloveReading:
        self._check_open()
        t = self.time
        theta = np.asarray(self.operator(t), dtype=np.float64)
        if theta.shape != (N_JOINTS,) or not np.isfinite(theta).all():
            raise ValueError(
                f"operator gave Θ of shape {theta.shape} at t = {t} (need finite (10,))"
            )
        psi = sensor_readings(theta, self.person, self._rng)
        self._k += 1
        self._last_read_time = t
        self.last_theta = theta.copy()
        return GloveReading(psi=psi, timestamp=t)

    def write_feedback(self, torques: ArrayLike) -> None:
        self._check_open()
        applied = check_feedback(torques, self.n_actuators)
        self.feedback.append((self._last_read_time, applied))
        if self._perceiver is not None:
            self._perceiver.feel(self._last_read_time, applied)

    def show(self, view: WorldView) -> None:
        """Pass ``view`` to the operator if they perceive (:class:`Perceiver`)."""
        if self._perceiver is not None:
            self._perceiver.see(view)

    def close(self) -> None:
        self._closed = True

    def __enter__(self) -> SimulatedGlove:
        return self


@dataclass(frozen=True)
class ReachPinchLiftTimings:
    """Phase boundaries of :class:`ReachPinchLift` [s] (each phase starts where one ends).

    Attributes:
        rest: hand open and still, 0 .. rest.
        reach: pre-shaping the hand while reaching (thumb opposes, index half closed).
        close: thumb and index close into the pinch.
        hold: pinch held (grasp settles).
        lift: wrist extends and deviates radially, pinch held.
        duration: end of the script; from ``lift`` on the lifted pinch is held still
            (phase ``"hold_lifted"``, which lasts beyond ``duration`` too).
    """

    rest: float = 0.3
    reach: float = 1.3
    close: float = 2.0
    hold: float = 2.5
    lift: float = 3.5
    duration: float = 4.5

    def __post_init__(self) -> None:
        times = (0.0, self.rest, self.reach, self.close, self.hold, self.lift, self.duration)
        if any(b <= a for a, b in itertools.pairwise(times)):
            raise ValueError(f"phase times must increase, got {times[1:]}")


#: Phase names of :class:`ReachPinchLift`, in order.
PHASES: tuple[str, ...] = ("rest", "reach", "close", "hold", "lift", "hold_lifted")


def min_jerk(s: float) -> float:
    """The minimum-jerk profile (Flash & Hogan 1985) from 0 to 1 at phase ``s`` (clipped to
    [0, 1]): zero velocity and acceleration at both ends."""
    s = min(max(s, 0.0), 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


class ReachPinchLift:
    """Scripted operator: reach, pinch (thumb and index pads touch), hold, lift, hold.

    Θ(t) is piecewise minimum-jerk between key poses: open hand -> pre-shape (thumb
    opposed, index half closed, other fingers curled) -> pinch (index angles from the
    two-link inverse kinematics that puts the pads together with ``pinch_force`` for this
    person's segment lengths) -> lifted (same fingers, wrist extended 0.3 rad and deviated
    radially 0.15 rad), held until ``timings.duration`` and after.

    Args:
        person: whose hand (segment lengths decide the pinch pose).
        timings: phase boundaries [s].
        pinch_force: how hard the pads press in the pinch [N].
        thumb: thumb CMC rotation/abduction and flexion of the pinch [rad].
        dip: index DIP angle in the pinch [rad] (pad pinch: small).
    """

    def __init__(
        self,
        person: PersonParams | None = None,
        timings: ReachPinchLiftTimings = ReachPinchLiftTimings(),
        *,
        pinch_force: float = 2.0,
        thumb: tuple[float, float] = (0.8, 0.6),
        dip: float = 0.25,
    ) -> None:
        self.person = person if person is not None else PersonParams.nominal()
        self.timings = timings
        self.pinch_force = float(pinch_force)
        cmc, flex = joint_index("thumb_cmc"), joint_index("thumb_flexion")
        i1, i2, i3 = INDEX_JOINTS
        wf, wd = joint_index("wrist_flexion"), joint_index("wrist_deviation")
        fm, fp = joint_index("fingers_mcp"), joint_index("fingers_pip")

        open_hand = np.zeros(N_JOINTS)
        open_hand[[wf, cmc, flex, fm, fp]] = [-0.1, 0.1, 0.1, 0.1, 0.1]

        pinch = open_hand.copy()
        pinch[[cmc, flex, i3]] = [thumb[0], thumb[1], dip]
        angles = index_pinch_angles(
            pinch[None, [cmc, flex]], np.array([dip]), np.array([pinch_force]), self.person
        )
        if not np.isfinite(angles).all():
            raise ValueError(f"no pinch pose for thumb {thumb} and DIP {dip} with this hand")
        pinch[[i1, i2]] = angles[0]
        pinch[[fm, fp]] = [1.2, 1.4]  # other fingers curled out of the way
        low, high = self.person.joint_limits
        if np.any(pinch < low) or np.any(pinch > high):
            raise ValueError(f"the pinch pose leaves the joint ranges: {pinch.round(3).tolist()}")

        pre = pinch.copy()
        pre[[i1, i2]] = 0.45 * pinch[[i1, i2]]
        pre[i3] = self.person.dip_coupling * pre[i2]  # free finger: DIP follows PIP
        pre[flex] = 0.5 * pinch[flex]

        lifted = pinch.copy()
        lifted[[wf, wd]] = [pinch[wf] - 0.3, pinch[wd] - 0.15]
        t = timings
        #: (start time [s], end time [s], pose at start, pose at end) of each moving phase.
        self._segments = (
            (t.rest, t.reach, open_hand, pre),
            (t.reach, t.close, pre, pinch),
            (t.hold, t.lift, pinch, lifted),
        )
        #: The key poses Θ [rad].
        self.poses = {"open": open_hand, "pre_shape": pre, "pinch": pinch, "lifted": lifted}

    @property
    def duration(self) -> float:
        """Length of the script [s]."""
        return self.timings.duration

    def phase(self, t: float) -> str:
        """Name of the phase at time ``t`` [s] (one of :data:`PHASES`)."""
        bounds = (
            self.timings.rest,
            self.timings.reach,
            self.timings.close,
            self.timings.hold,
            self.timings.lift,
        )
        for name, end in zip(PHASES, bounds, strict=False):
            if t < end:
                return name
        return PHASES[-1]

    def __call__(self, t: float) -> NDArray[np.float64]:
        """Intended joint angles Θ(t) ``(10,)`` [rad]."""
        pose = self.poses["open"]
        for start, end, a, b in self._segments:
            if t >= start:
                pose = a + (b - a) * min_jerk((t - start) / (end - start))
        return np.array(pose, dtype=np.float64)

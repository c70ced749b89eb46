"""The library's skill motions the assistant completes (:class:`SkillMotion`,
:func:`load_motions`): each glove skill's typical trajectory of the operator's joint targets
from its demonstrations' skill start (aligned in amplitude and speed before they are
averaged, :func:`align_demonstrations`), less the holding skill's (:data:`HOLD_SKILL`), on
the joints it moves, with how much persons differ in amplitude and speed, and where the
demonstrations leave the pen (:attr:`SkillMotion.goal_height`,
:attr:`SkillMotion.tilt_per_amplitude`: what a person in the loop holds by sight once the
motion is done).

A skill acquired on line (:func:`~ias_gym.assist.recognition.acquire_skill`, stored under a
name of its own) is a skill like the shipped ones here: every glove session that records
where its motion starts counts. A skill with few demonstrations borrows the other skills'
spread (:func:`shrunk_spread`): one demonstration says nothing of how persons differ.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ias_gym.assist.sessions import pen_axis
from ias_gym.assist.stream import THETA_INFO
from ias_gym.envs.glove_world import OBSERVATION
from ias_gym.errors import InputError
from ias_gym.glove.hand import JOINT_NAMES, N_JOINTS
from ias_gym.glove.skills import SKILLS
from ias_gym.skills.db import SkillDB
from ias_gym.skills.glove_session import motion_window
from ias_gym.skills.transfer import shipped_skill_db, skill_start_index

FloatArray = NDArray[np.float64]

#: The joint that raises and lowers the pen in the hand (the lift's) ...
WRIST_FLEXION = JOINT_NAMES.index("wrist_flexion")
#: ... and the one that tilts it (the tilts' and see-saws').
WRIST_PRONATION = JOINT_NAMES.index("wrist_pronation")


def pen_elevation(quat: FloatArray) -> FloatArray:
    """``(T,)`` the angle of the pen's axis (its body x, :func:`pen_axis`) above the
    horizontal [rad], from ``(T, 4)`` world quaternions (w, x, y, z): positive when its +x
    end is up."""
    return np.asarray(np.arcsin(np.clip(pen_axis(quat)[:, 2], -1.0, 1.0)), dtype=np.float64)


@dataclass(frozen=True)
class ObjectMeasures:
    """What one demonstration does to the pen (:func:`object_measures`)."""

    height_end: float  # [m] above its start, at the end
    rise_per_flexion: float  # [m/rad] in the lift
    tilt_change: float  # [rad] of the axis from the skill's start to the end
    tilt_per_pronation: float  # [rad/rad] over the skill's motion


def object_measures(obs: FloatArray, theta: FloatArray, k: int) -> ObjectMeasures:
    """A demonstration's :class:`ObjectMeasures` from its observations ``(T, ...)``, the
    operator's targets ``(T, 10)`` and its skill start's index ``k``."""
    z = obs[:, OBSERVATION["pen_position"]][:, 2]
    tilt = pen_elevation(obs[:, OBSERVATION["pen_quat"]])
    turn = theta[k:, WRIST_PRONATION] - theta[k, WRIST_PRONATION]
    slope = float("nan")
    if np.ptp(turn) > MOVING_JOINT:
        slope = float(np.polyfit(turn, tilt[k:] - tilt[k], 1)[0])
    return ObjectMeasures(
        float(z[-END_SAMPLES:].mean()),
        lift_slope(z[:k], theta[:k, WRIST_FLEXION]),
        float(tilt[-END_SAMPLES:].mean() - tilt[k]),
        slope,
    )


#: A skill's template moves a joint if its range over the motion, beyond the holding
#: skill's, exceeds this [rad] (under a third of the smallest, the fast see-saw's 0.1 rad)
#: and what its demonstrations move it by chance (:func:`moving_joints`).
MOVING_JOINT = 0.03
#: The skill that holds the pen still after the lift: what the others share.
HOLD_SKILL = "lift_hold"
#: A template's motion is done once its principal joint stays within this share of its
#: range of where it ends [-].
SETTLED = 0.05
#: The pen's height [m] at a demonstration's end is read as the mean over its last this many
#: samples.
END_SAMPLES = 30


@dataclass(frozen=True)
class SkillMotion:
    """How one skill moves the joints, from its demonstrations.

    Attributes:
        name: the skill.
        tau: ``(T,)`` time since the skill's start [s] (the library's typical person).
        delta: ``(T, J)`` the typical joint targets less those at the start [rad], on ``joints``.
        joints: the joints the skill moves (indices into ``JOINT_NAMES``).
        amplitude_sd: the standard deviation of the demonstrations' amplitudes relative to
            the mean [-] ...
        speed_sd: ... and of the logarithm of their speeds relative to the mean [-] (each
            demonstration's best pair on :data:`DEMO_SPEEDS`, least squares on ``joints``):
            how much persons differ, the prior of an operator's fit.
        goal_height: where the demonstrations leave the pen: the median over them of the
            pen's height above its start at their end [m].
        rise_per_flexion: how much the pen rises per radian of wrist flexion in the
            demonstrations' lifts [m/rad] (negative: extension raises it; the median over
            them of the least-squares slope, :func:`lift_slope`).
        tilt_per_amplitude: how far the demonstrations turn the pen's axis up from the
            skill's start to their end [rad] (:func:`pen_elevation`), per unit of their
            fitted amplitude: the median over them; an operator of amplitude ``a`` means
            ``a`` times it.
        tilt_per_pronation: how much the pen's axis rises per radian of wrist pronation over
            the demonstrations' motions [rad/rad] (the median least-squares slope; NaN where
            the skill turns the wrist less than :data:`MOVING_JOINT`).
    """

    name: str
    tau: FloatArray
    delta: FloatArray
    joints: NDArray[np.int64]
    amplitude_sd: float
    speed_sd: float
    goal_height: float = float("nan")
    rise_per_flexion: float = float("nan")
    tilt_per_amplitude: float = float("nan")
    tilt_per_pronation: float = float("nan")

    @property
    def principal(self) -> int:
        """The position in :attr:`joints` of the joint the skill moves most."""
        return int(np.argmax(np.ptp(self.delta, axis=0)))

    @property
    def end_tau(self) -> float:
        """The template's time [s] by which its motion is done: the last at which its
        principal joint is still farther than :data:`SETTLED` of its range from where it
        ends."""
        d = self.delta[:, self.principal]
        moving = np.flatnonzero(np.abs(d - d[-1]) > SETTLED * np.ptp(d))
        return float(self.tau[moving[-1] + 1]) if moving.size else 0.0

    def at(self, tau: FloatArray) -> FloatArray:
        """``(len(tau), J)`` the motion at times ``tau`` (0 before the start, held after)."""
        return np.stack(
            [np.interp(tau, self.tau, self.delta[:, j], left=0.0) for j in range(len(self.joints))],
            axis=-1,
        )


def load_motions(db_path: str | Path | None = None) -> dict[str, SkillMotion]:
    """Every glove skill's :class:`SkillMotion` in a library (default: the shipped one): the
    aligned mean of its successful demonstrations' operator targets (``glove_theta``; the
    hand's joint angles where a recording lacks them) from their skill start, less the
    holding skill's (:data:`HOLD_SKILL`); skills that move no joint beyond it are left out.
    A failed session (its ``is_success`` false) is no demonstration of its skill (as in
    :func:`~ias_gym.assist.recognition.load_library`).

    Raises:
        InputError: the file does not exist.
    """
    path = Path(db_path) if db_path is not None else shipped_skill_db()
    if not path.is_file():
        raise InputError(f"skill library {path} does not exist (give an existing --db)")
    groups: dict[str, list[tuple[FloatArray, FloatArray]]] = {}
    measures: dict[str, list[ObjectMeasures]] = {}  # what each demonstration does to the pen
    with SkillDB(path, readonly=True) as db:
        for skill_id in db.ids():
            skill = db.get(skill_id)
            if skill.person_id is None or not skill.is_success:
                continue
            if skill.name not in SKILLS and motion_window(skill) is None:
                continue  # neither a shipped glove skill nor a session that says its start
            k = skill_start_index(skill)
            time = np.asarray(skill.model.time, dtype=np.float64)
            demo = skill.demonstration
            obs = np.asarray(demo.observations, dtype=np.float64)[: len(time)]
            targets = demo.infos.get(THETA_INFO) if demo.infos else None
            if targets is not None:  # the operator's targets, what the assistant reads
                theta = np.asarray(targets, dtype=np.float64)[: len(time)]
            else:  # a recording without them: the hand's angles
                theta = obs[:, OBSERVATION["joint_angles"]]
            groups.setdefault(skill.name, []).append((time[k:] - time[k], theta[k:] - theta[k]))
            measures.setdefault(skill.name, []).append(object_measures(obs, theta, k))
    means: dict[str, tuple[FloatArray, FloatArray]] = {}
    resampled: dict[str, FloatArray] = {}  # (D, T, 10) each demonstration on the mean's grid
    for name, demos in groups.items():
        end = min(float(t[-1]) for t, _ in demos)
        tau = np.arange(0.0, end, 0.01)
        each = np.array(
            [np.stack([np.interp(tau, t, d[:, j]) for j in range(N_JOINTS)], 1) for t, d in demos]
        )
        means[name], resampled[name] = (tau, each.mean(axis=0)), each
    # What every skill shares after its start (the grip settling, the lift's end) is the
    # holding skill's motion; each skill's own motion is what it does beyond that.
    shared = means.get(HOLD_SKILL)
    chance = np.zeros(N_JOINTS)
    if shared is not None:
        chance = chance_ranges(resampled[HOLD_SKILL])
    aligned = {}
    for name, (tau, mean) in means.items():
        base = np.zeros_like(mean)
        if shared is not None:
            base = np.stack(
                [np.interp(tau, shared[0], shared[1][:, j]) for j in range(N_JOINTS)], 1
            )
        each = np.ptp(resampled[name] - base[None], axis=1)  # (D, J) every demonstration's
        joints = moving_joints(np.ptp(mean - base, axis=0), each, chance)
        if not joints.size:
            continue
        own = np.array([(d - base)[:, joints] for d in resampled[name]])
        aligned[name] = (tau, joints, *align_demonstrations(tau, own))
    # how much persons differ, pooled over the skills: what a skill with one demonstration
    # borrows
    spreads = [
        (float(np.std(a)), float(np.std(np.log(v))))
        for _, _, _, a, v in aligned.values()
        if len(a) > 1
    ]
    pooled = np.median(spreads, axis=0) if spreads else np.zeros(2)
    return {
        name: SkillMotion(
            name,
            tau,
            m,
            joints,
            shrunk_spread(amps, float(pooled[0])),
            shrunk_spread(np.log(speeds), float(pooled[1])),
            *_object_goals(measures[name], amps),
        )
        for name, (tau, joints, m, amps, speeds) in aligned.items()
    }


def chance_ranges(hold: FloatArray) -> FloatArray:
    """``(J,)`` how far one person's template moves each joint in no skill [rad]: the largest
    range, over the holding skill's demonstrations ``hold`` ``(D, T, J)``, of one of them
    about their mean (the grip's and the wrist's corrections by sight that every session
    has). A mean of ``n`` demonstrations moves a joint by chance about ``1 / sqrt(n)`` of it.

    With one demonstration of a tilt, its person's corrections of the wrist's flexion and of
    the index (0.03-0.05 rad) would otherwise count as the skill's motion, and an operator's
    fit, made to explain joints they move otherwise, shrinks its amplitude to a third."""
    h = np.asarray(hold, dtype=np.float64)
    if len(h) < 2:
        return np.zeros(h.shape[-1])
    return np.ptp(h - h.mean(axis=0), axis=1).max(axis=0)


def moving_joints(ranges: FloatArray, each: FloatArray, chance: FloatArray) -> NDArray[np.int64]:
    """The joints a template moves: the mean's ``ranges`` ``(J,)`` beyond the holding skill's
    [rad] above :data:`MOVING_JOINT` and above ``chance / sqrt(n)`` (:func:`chance_ranges`),
    and the ranges ``each`` ``(n, J)`` of more than half of its ``n`` demonstrations above
    :data:`MOVING_JOINT` and ``chance``: one person's grip or correction, diluted in a mean as
    ``1 / n`` only, is no motion of the skill."""
    floor = np.maximum(MOVING_JOINT, np.asarray(chance, dtype=np.float64))
    every = np.atleast_2d(np.asarray(each, dtype=np.float64))
    mean_moves = np.asarray(ranges, dtype=np.float64) > np.maximum(
        MOVING_JOINT, floor / np.sqrt(len(every))
    )
    most_move = (every > floor).mean(axis=0) > 0.5
    return np.flatnonzero(mean_moves & most_move)


def _median(values: list[float]) -> float:
    """The median of the finite ``values``; NaN if there are none."""
    finite = [v for v in values if np.isfinite(v)]
    return float(np.median(finite)) if finite else float("nan")


def _object_goals(
    measures: list[ObjectMeasures], amplitudes: FloatArray
) -> tuple[float, float, float, float]:
    """A skill's ``(goal_height, rise_per_flexion, tilt_per_amplitude, tilt_per_pronation)``
    from its demonstrations' measures and fitted amplitudes (in the same order)."""
    return (
        _median([m.height_end for m in measures]),
        _median([m.rise_per_flexion for m in measures]),
        _median([m.tilt_change / a for m, a in zip(measures, amplitudes, strict=True)]),
        _median([m.tilt_per_pronation for m in measures]),
    )


#: The lift is read between these shares of the pen's height at the skill's start [-].
LIFT_SHARES = (0.1, 0.9)


def lift_slope(height: FloatArray, flexion: FloatArray) -> float:
    """The least-squares slope [m/rad] of the pen's ``height`` on the wrist ``flexion``
    over a demonstration's lift (its samples before the skill's start): those where the pen
    is between :data:`LIFT_SHARES` of its height at the start, rising; NaN if there are
    fewer than three."""
    h, f = np.asarray(height, dtype=np.float64), np.asarray(flexion, dtype=np.float64)
    if len(h) < 3:
        return float("nan")
    low, high = (share * float(h[-1]) for share in LIFT_SHARES)
    rising = (h > low) & (h < high)
    if rising.sum() < 3 or np.ptp(f[rising]) <= 0:
        return float("nan")
    return float(np.polyfit(f[rising], h[rising], 1)[0])


def shrunk_spread(values: FloatArray, pooled: float) -> float:
    """The standard deviation of ``values`` with ``pooled`` counted as one more
    observation of the squared deviation: ``sqrt((sum (x - mean)^2 + pooled^2) / n)``.

    One demonstration gives ``pooled``; many give their own spread (plus ``pooled^2 / n``).
    """
    x = np.asarray(values, dtype=np.float64)
    return float(np.sqrt((float(((x - x.mean()) ** 2).sum()) + pooled**2) / len(x)))


#: Rounds of aligning the demonstrations in amplitude and speed before they are averaged.
ALIGN_ROUNDS = 2
#: The speeds relative to the library's mean a demonstration is fitted on [-].
DEMO_SPEEDS = np.linspace(0.6, 1.6, 51)


def align_demonstrations(
    tau: FloatArray, demos: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The typical motion of ``demos`` ``(D, T, J)`` (on times ``tau``) and each one's
    amplitude and speed relative to it.

    A plain mean of persons who move at different speeds is blurred (a see-saw's phase
    spreads over its cycles), so each demonstration is fitted as ``a m(v tau)`` to the mean
    (:func:`_amplitude_speed`), brought to the typical amplitude and speed (the mean of the
    ``a``, the geometric mean of the ``v``) and averaged again, :data:`ALIGN_ROUNDS` times.

    Returns:
        ``(mean (T, J), amplitudes (D,), speeds (D,))``.
    """
    m = demos.mean(axis=0)
    for _ in range(ALIGN_ROUNDS):
        amps, speeds = np.array([_amplitude_speed(tau, m, d) for d in demos]).T
        typical_a, typical_v = float(np.mean(amps)), float(np.exp(np.mean(np.log(speeds))))
        m = np.mean(
            [
                _resample(tau, d, typical_v / v) * (typical_a / a)
                for d, a, v in zip(demos, amps, speeds, strict=True)
            ],
            axis=0,
        )
    amps, speeds = np.array([_amplitude_speed(tau, m, d) for d in demos]).T
    return m, amps, speeds


def _resample(tau: FloatArray, values: FloatArray, scale: float) -> FloatArray:
    """``values`` (on ``tau``) read at ``scale * tau`` (held beyond the end)."""
    return np.stack([np.interp(scale * tau, tau, values[:, j]) for j in range(values.shape[1])], 1)


def _amplitude_speed(tau: FloatArray, mean: FloatArray, demo: FloatArray) -> tuple[float, float]:
    """The amplitude and speed ``(a, v)`` for which ``a mean(v tau)`` fits ``demo`` best
    (least squares, ``a`` in closed form for each ``v`` of :data:`DEMO_SPEEDS`)."""
    best = (np.inf, 1.0, 1.0)
    for v in DEMO_SPEEDS:
        m = _resample(tau, mean, float(v))
        a = float((m * demo).sum() / max(float((m * m).sum()), 1e-12))
        res = float(((a * m - demo) ** 2).sum())
        if res < best[0]:
            best = (res, a, float(v))
    return best[1], best[2]

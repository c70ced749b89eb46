"""Sessions of ``IAS-GloveAssist-v0`` with and without an assistant, and how they are judged.

A session **succeeds** (:func:`session_success`) when

- the env's own success holds at the end (the pen lifted, or for ``lift_place`` put back,
  still pinched) and both pads touch the pen at the end, and
- the pen's motion relative to its pose at the skill's start
  (:func:`~ias_gym.glove.skills.skill_start_time`), from there to the end, stays within
  :data:`POSITION_TOLERANCE` (RMS of the centre's displacement error) and
  :data:`ROTATION_TOLERANCE` (RMS of the axis' change error: the skills tilt and turn the
  pen's axis; its roll about the axis, which the pads set at random, is no part of a skill)
  of the **unimpaired person's**
  session: the same person, skill and seed with ``impairment="none"`` and no assistant.

The tolerances are a few times the spread of unimpaired sessions over seeds (the glove's
noise): measured in docs/assistance.md.

**Intervention** (:attr:`SessionResult.intervention`): the mean size of the assistant's
joint offsets over the mean size of the operator's own joint motion,
``mean_t |scale a_t|_1 / mean_t |Θ_t - Θ_0|_1`` (Θ: the operator's calibrated targets,
both over the 10 joints and the whole session) [-]; 0 without an assistant.

**Intent-switch latency**: after the operator switches from skill A to B at ``t_s``, the
time [s] until the assistant's recogniser puts B first and keeps it there to the end
(:attr:`SessionResult.switch_latency_s`; ``inf`` if it never does).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from ias_gym.glove.skills import SKILL_TIMINGS, skill_start_time

FloatArray = NDArray[np.float64]

#: RMS distance of the pen's centre from the unimpaired session's, from the skill start [m].
POSITION_TOLERANCE = 0.003
#: RMS angle between the pen's orientation and the unimpaired session's [rad] (5 deg).
ROTATION_TOLERANCE = math.radians(5.0)

#: Episode time from which a reference session must pinch the pen without a break [s]: the
#: start of the skills' lift.
HELD_FROM = SKILL_TIMINGS.hold - SKILL_TIMINGS.reach

#: Columns of the glove observation: pen centre relative to its start, its quaternion.
OBS_PEN = slice(20, 23)
OBS_QUAT = slice(23, 27)


class Assistant(Protocol):
    """What drives the assist env's action: an assistant (or an SB3-style policy wrapper)."""

    def reset(self, env: Any) -> None:
        """Start a session on ``env`` (the unwrapped glove env, just reset)."""

    def act(self, env: Any) -> FloatArray:
        """The action ``(10,)`` in [-1, 1] for the env's next step."""

    def posterior(self) -> dict[str, float]:
        """The recogniser's posterior after the last :meth:`act` (empty if none)."""


@dataclass
class SessionResult:
    """One session.

    Attributes:
        times: ``(T,)`` episode time of each step's end [s].
        pen_position: ``(T, 3)`` pen centre relative to its start [m].
        pen_quat: ``(T, 4)`` pen orientation quaternions.
        env_success: the env's ``is_success`` at the end.
        held: both pads touch the pen at the end.
        skill_start: episode time of the skill's start [s].
        intervention: mean |offset| over mean operator motion [-] (module docstring).
        top_skill: ``(T,)`` the recogniser's most probable skill (or ``"unknown"``) at each
            step ("" without a recogniser).
        switch_latency_s: intent-switch latency [s] (NaN without a switch).
        success: filled in by :func:`session_success` against a reference.
        pinched: ``(T,)`` both pads touch the pen at the end of each step.
    """

    times: FloatArray
    pen_position: FloatArray
    pen_quat: FloatArray
    env_success: bool
    held: bool
    skill_start: float
    intervention: float
    top_skill: list[str] = field(default_factory=list)
    switch_latency_s: float = math.nan
    success: bool = False
    pinched: FloatArray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    def held_throughout(self) -> bool:
        """Both pads touched the pen at every step from the lift's start
        (:data:`HELD_FROM`) to the end, and the env's success held at the end."""
        after = self.times >= HELD_FROM - 1e-9
        return bool(self.env_success and self.held and np.all(self.pinched[after]))


def _switch_latency(times: FloatArray, top: list[str], target: str, t_switch: float) -> float:
    """Time from ``t_switch`` until ``top`` is ``target`` from then to the end [s]."""
    if not top:
        return math.nan
    wrong = [i for i, (t, s) in enumerate(zip(times, top, strict=True)) if s != target]
    after = [i for i in wrong if times[i] >= t_switch]
    if not after:
        return 0.0
    last = after[-1]
    if last == len(times) - 1:
        return math.inf
    return float(times[last + 1] - t_switch)


def run_session(
    env: gym.Env[Any, Any],
    assistant: Assistant | None,
    seed: int,
    options: dict[str, Any] | None = None,
) -> SessionResult:
    """Run one session of ``env`` (an ``IAS-GloveAssist-v0``) to its end.

    Args:
        env: the env (wrappers allowed).
        assistant: gives the actions; None: zero actions (the operator alone).
        seed: the reset seed.
        options: reset options (e.g. a perturbed start, ``tests/closed_loop.py``).

    Returns:
        The session's trajectory and measures (``success`` not yet judged).
    """
    u: Any = env.unwrapped
    obs, info = env.reset(seed=seed, options=options)
    if assistant is not None:
        assistant.reset(u)
    scale = float(u.config.action_scale)
    times, pos, quat, offsets, motion, top, pinched = [], [], [], [], [], [], []
    theta0: FloatArray | None = None
    done = False
    while not done:
        if assistant is None:
            action = np.zeros(env.action_space.shape or (10,))
        else:
            action = np.clip(np.asarray(assistant.act(u), dtype=np.float64), -1.0, 1.0)
            post = assistant.posterior()
            top.append(max(post, key=post.__getitem__) if post else "")
        obs, _, terminated, truncated, info = env.step(action)
        theta = np.asarray(info["operator_theta"])
        theta0 = theta if theta0 is None else theta0
        offsets.append(float(np.abs(scale * action).sum()))
        motion.append(float(np.abs(theta - theta0).sum()))
        times.append(float(obs[38]))
        pos.append(np.asarray(obs[OBS_PEN]))
        quat.append(np.asarray(obs[OBS_QUAT]))
        pinched.append(bool(info["index_contact"] and info["thumb_contact"]))
        done = bool(terminated or truncated)
    skill = str(u.config.skill)
    mean_motion = float(np.mean(motion)) if motion else 0.0
    result = SessionResult(
        times=np.asarray(times),
        pen_position=np.asarray(pos),
        pen_quat=np.asarray(quat),
        env_success=bool(info["is_success"]),
        held=bool(info["index_contact"] and info["thumb_contact"]),
        skill_start=skill_start_time(skill, u.person.person_id),
        intervention=float(np.mean(offsets)) / mean_motion if mean_motion > 0 else 0.0,
        top_skill=top,
        pinched=np.asarray(pinched, dtype=bool),
    )
    if getattr(u, "switch_to", None) is not None:
        result.switch_latency_s = _switch_latency(
            result.times, top, str(u.switch_to), float(u.switch_time)
        )
    return result


def pen_axis(quat: FloatArray) -> FloatArray:
    """``(T, 3)`` the pen's axis (its body x) in the world from ``(T, 4)`` quaternions
    (w, x, y, z): the first column of the rotation matrix."""
    w, x, y, z = np.asarray(quat, dtype=np.float64).T
    return np.stack([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)], axis=1)


def pose_errors(result: SessionResult, reference: SessionResult) -> tuple[float, float]:
    """RMS position [m] and axis [rad] error of ``result``'s pen motion against
    ``reference``'s from the reference's skill start ``t_s`` to the end (``inf`` if
    ``result`` ended early).

    The motion is the skill's, relative to the pen's pose at ``t_s`` (as skill transfer
    reads a skill: :mod:`ias_gym.skills.transfer`): the centre's displacement
    ``p(t) - p(t_s)`` and the axis' change ``a(t) - a(t_s)`` (a chord of the unit sphere:
    the axis' rotation angle for small angles, with its direction).
    """
    n = len(reference.times)
    if len(result.times) < n:
        return math.inf, math.inf
    start = int(np.searchsorted(reference.times, reference.skill_start))

    def motion(r: SessionResult) -> tuple[FloatArray, FloatArray]:
        pos = r.pen_position[start:n] - r.pen_position[start]
        axis = pen_axis(r.pen_quat[start:n])
        return pos, axis - axis[0]

    (p1, a1), (p0, a0) = motion(result), motion(reference)
    dp, da = p1 - p0, a1 - a0
    return (
        float(np.sqrt(np.mean(np.sum(dp * dp, axis=1)))),
        float(np.sqrt(np.mean(np.sum(da * da, axis=1)))),
    )


def session_success(result: SessionResult, reference: SessionResult) -> bool:
    """Judge ``result`` against the unimpaired ``reference`` (module docstring); also sets
    ``result.success``."""
    dp, dr = pose_errors(result, reference)
    ok = (
        result.env_success and result.held and dp <= POSITION_TOLERANCE and dr <= ROTATION_TOLERANCE
    )
    result.success = bool(ok)
    return result.success


@dataclass
class ImpairmentScore:
    """Success with and without the assistant for one impairment.

    Attributes:
        success_unassisted: share of sessions that succeed without the assistant [-].
        success_assisted: with it [-].
        intervention: the assistant's mean intervention [-] (module docstring).
        sessions: number of sessions of each kind that count.
        excluded: sessions left out because the unimpaired person's own session failed (the
            pen not lifted 3 cm or not held at the end) or lost a pad on the way
            (:meth:`SessionResult.held_throughout`): no reference to reach.
    """

    success_unassisted: float
    success_assisted: float
    intervention: float
    sessions: int
    excluded: int = 0

    def to_json(self) -> dict[str, float | None]:
        """The three shares as a JSON object (``sessions`` and ``excluded`` as well; null
        for a share of no session)."""

        def number(x: float) -> float | None:
            return None if math.isnan(x) else x

        return {
            "success_unassisted": number(self.success_unassisted),
            "success_assisted": number(self.success_assisted),
            "intervention": number(self.intervention),
            "sessions": self.sessions,
            "excluded": self.excluded,
        }


def evaluate_assistance(
    make_assistant: Any,
    persons: list[str],
    impairments: list[str],
    episodes: int,
    seed: int,
    skills: tuple[str, ...] | None = None,
    progress: Any = None,
    env_kwargs: dict[str, Any] | None = None,
) -> dict[str, ImpairmentScore]:
    """Success with and without an assistant per impairment (module docstring).

    For every person and impairment, ``episodes`` sessions: session ``i`` performs skill
    ``skills[i % len(skills)]`` from reset seed ``seed + i``, once without and once with
    the assistant, each judged against the unimpaired session of the same person, skill and
    seed (run once and reused). A session whose unimpaired reference fails itself (the
    env's success, or a pad off the pen at any step from the lift on: a re-grasp makes the
    intended motion chaotic) is left out and counted in ``excluded``.

    Args:
        make_assistant: ``() -> Assistant``, a fresh assistant.
        persons: person ids.
        impairments: impairment names (:data:`~ias_gym.assist.impairments.IMPAIRMENTS`).
        episodes: sessions per person and impairment.
        seed: the first reset seed.
        skills: the skills to cycle through (default all six glove skills).
        progress: called with no argument after every session pair (e.g. a bar's update).
        env_kwargs: further ``gym.make`` kwargs (e.g. ``strength``).

    Returns:
        ``{impairment: ImpairmentScore}``.
    """
    from ias_gym.glove.skills import SKILLS

    skills = skills or SKILLS
    extra = dict(env_kwargs or {})
    references: dict[tuple[str, str, int], SessionResult] = {}
    out = {}
    for imp in impairments:
        ok_u, ok_a, interv = [], [], []
        excluded = 0
        for person in persons:
            for i in range(episodes):
                skill, s = skills[i % len(skills)], seed + i
                key = (person, skill, s)
                if key not in references:
                    ref_env = gym.make("IAS-GloveAssist-v0", person_id=person, skill=skill)
                    references[key] = run_session(ref_env, None, s)
                    ref_env.close()
                ref = references[key]
                if not ref.held_throughout():
                    excluded += 1
                    if progress is not None:
                        progress()
                    continue
                env = gym.make(
                    "IAS-GloveAssist-v0", person_id=person, skill=skill, impairment=imp, **extra
                )
                unassisted = run_session(env, None, s)
                assisted = run_session(env, make_assistant(), s)
                env.close()
                ok_u.append(session_success(unassisted, references[key]))
                ok_a.append(session_success(assisted, references[key]))
                interv.append(assisted.intervention)
                if progress is not None:
                    progress()
        nan = math.nan
        out[imp] = ImpairmentScore(
            float(np.mean(ok_u)) if ok_u else nan,
            float(np.mean(ok_a)) if ok_a else nan,
            float(np.mean(interv)) if interv else nan,
            len(ok_u),
            excluded,
        )
    return out


def switch_latency(
    make_assistant: Any,
    persons: list[str],
    pairs: list[tuple[str, str]],
    switch_time: float,
    seed: int,
) -> list[float]:
    """Intent-switch latencies [s] (module docstring) of an assistant, one per person and
    (from, to) skill pair, with the unimpaired operator switching at ``switch_time`` [s]."""
    out = []
    for person in persons:
        for a, b in pairs:
            env = gym.make(
                "IAS-GloveAssist-v0",
                person_id=person,
                skill=a,
                switch_to=b,
                switch_time=switch_time,
            )
            out.append(run_session(env, make_assistant(), seed).switch_latency_s)
            env.close()
    return out

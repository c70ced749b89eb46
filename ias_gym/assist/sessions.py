"""Sessions of ``IAS-GloveAssist-v0`` with and without an assistant, and how they are judged.

A session **succeeds** (:func:`session_success`) when

- the env's own success holds at the end (the pen lifted, or for ``lift_place`` put back,
  still pinched) and both pads touch the pen at the end, and
- the pen's motion relative to its pose at the skill's start (the env's ``skill_start``, the
  phase a recorded session stores), from there to the end and at the best time shift up to
  :data:`MAX_TIME_SHIFT`, stays within :data:`POSITION_TOLERANCE` (RMS of the centre's
  displacement error) and :data:`ROTATION_TOLERANCE` (RMS of the axis' change error: the
  skills tilt and turn the pen's axis; its roll about the axis, which the pads set at random,
  is no part of a skill) of the **unimpaired person's**
  session: the same person, skill and seed with ``impairment="none"`` and no assistant
  (for ``hand_size``, with the same resized hand:
  :func:`~ias_gym.glove.impairments.reference_kwargs`).

The tolerances are a few times the spread of unimpaired sessions over seeds (the glove's
noise): measured in docs/assistance.md.

**Intervention** (:attr:`SessionResult.intervention`): the mean size of the assistant's
joint offsets over the mean size of the operator's own joint motion,
``mean_t |scale a_t|_1 / mean_t |Θ_t - Θ_0|_1`` (Θ: the operator's calibrated targets,
both over the 10 joints and the whole session) [-]; 0 without an assistant.

**Intent-switch latency**: after the operator switches from skill A to B at ``t_s``, the
time [s] until the assistant's recogniser puts B first and keeps it there to the end
(:attr:`SessionResult.switch_latency_s`; ``inf`` if it never does).

Judging an assistant over persons and impairments against the unimpaired reference
sessions is :mod:`ias_gym.assist.assistance_evaluation`'s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from ias_gym.envs.glove_world import OBSERVATION
from ias_gym.glove.hand import N_JOINTS
from ias_gym.glove.skills import SKILL_TIMINGS
from ias_gym.rollout import rollout

FloatArray = NDArray[np.float64]

#: RMS distance of the pen's centre from the unimpaired session's, from the skill start [m].
POSITION_TOLERANCE = 0.003
#: RMS angle between the pen's orientation and the unimpaired session's [rad] (5 deg).
ROTATION_TOLERANCE = math.radians(5.0)
#: Largest time shift [s] between a session and the reference at which their pen motions are
#: compared (:func:`pose_errors`): a person's reaction time (0.15-0.2 s), and less than half
#: the period of the fastest skill motion (the fast see-saw's: 0.65 s for the fastest
#: person), so no shift turns one skill into another.
MAX_TIME_SHIFT = 0.15

#: Episode time from which a reference session must pinch the pen without a break [s]: the
#: start of the skills' lift.
HELD_FROM = SKILL_TIMINGS.hold - SKILL_TIMINGS.reach
#: Episode time at which the lift ends and the skill's own motion may begin [s].
LIFT_END = SKILL_TIMINGS.lift - SKILL_TIMINGS.reach

#: The glove observation's pen centre relative to its start and its quaternion.
OBS_PEN = OBSERVATION["pen_position"]
OBS_QUAT = OBSERVATION["pen_quat"]
_OBS_TIME = OBSERVATION["time"].start


class Assistant(Protocol):
    """What drives the assist env's action: an assistant (or an SB3-style policy wrapper)."""

    def reset(self, env: Any) -> None:
        """Start a session on ``env`` (the unwrapped glove env, just reset)."""

    def act(self, env: Any) -> FloatArray:
        """The action ``(10,)`` in [-1, 1] for the env's next step."""

    def posterior(self) -> dict[str, float]:
        """The recogniser's posterior after the last :meth:`act` (empty if none)."""


class AssistantPolicy:
    """An :class:`Assistant` as a policy of :func:`~ias_gym.rollout.rollout` (SB3's
    ``predict``), or the operator alone (``assistant=None``: zero actions).

    At an episode's start the assistant is reset on the unwrapped env; every step it acts on
    the env (not on the observation), its action clipped to [-1, 1], and its recogniser's
    most probable skill is appended to :attr:`top` (``""`` if it has no posterior).

    Args:
        env: the assist env the rollout steps (wrappers allowed).
        assistant: the assistant, or None.
    """

    def __init__(self, env: gym.Env[Any, Any], assistant: Any) -> None:
        self.env: Any = env.unwrapped
        self.assistant: Any = assistant
        self.shape = env.action_space.shape or (N_JOINTS,)
        #: The recogniser's top skill at each step so far (empty without an assistant).
        self.top: list[str] = []

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[FloatArray, Any]:
        """The assistant's action: an assistant that reads observations
        (``reads_observations``, :class:`~ias_gym.assist.policy.ObservationAssistant`) acts
        on ``observation``, any other on the env's current state."""
        if self.assistant is None:
            return np.zeros(self.shape), state
        on_obs = getattr(self.assistant, "reads_observations", False)
        if episode_start:
            self.assistant.reset() if on_obs else self.assistant.reset(self.env)
            self.top = []
        raw = self.assistant.act(observation if on_obs else self.env)
        action = np.clip(np.asarray(raw, dtype=np.float64), -1.0, 1.0)
        post = self.assistant.posterior()
        self.top.append(max(post, key=post.__getitem__) if post else "")
        return action, state


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


def intent_latency(times: FloatArray, top: Sequence[str], target: str, t_switch: float) -> float:
    """The intent-switch latency [s]: the time from ``t_switch`` until the most probable
    skill ``top`` (one per time of ``times``) is ``target`` from then to the end; 0 if it
    is already, ``inf`` if it is not at the end, NaN without a trace."""
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
    assistant: Any,
    seed: int,
    options: dict[str, Any] | None = None,
) -> SessionResult:
    """Run one session of ``env`` (an ``IAS-GloveAssist-v0``) to its end.

    Args:
        env: the env (wrappers allowed).
        assistant: gives the actions (an :class:`Assistant`, or one that reads
            observations: :class:`~ias_gym.assist.policy.ObservationAssistant`); None: zero
            actions (the operator alone).
        seed: the reset seed.
        options: reset options (e.g. a perturbed start, ``tests/closed_loop.py``).

    Returns:
        The session's trajectory and measures (``success`` not yet judged).
    """
    u: Any = env.unwrapped
    policy = AssistantPolicy(env, assistant)
    trajectory = rollout(env, policy, seed, reset_options=options)
    assert trajectory.observations is not None and trajectory.infos is not None
    obs, infos = trajectory.observations[1:], trajectory.infos[1:]  # after each step
    info = trajectory.final_info
    scale = float(u.config.action_scale)
    theta = [np.asarray(i["operator_theta"]) for i in infos]
    offsets = [float(np.abs(scale * a).sum()) for a in trajectory.actions]
    motion = [float(np.abs(t - theta[0]).sum()) for t in theta]
    pinched = [bool(i["index_contact"] and i["thumb_contact"]) for i in infos]
    top = policy.top
    mean_motion = float(np.mean(motion)) if motion else 0.0
    result = SessionResult(
        times=obs[:, _OBS_TIME].copy(),
        pen_position=obs[:, OBS_PEN].copy(),
        pen_quat=obs[:, OBS_QUAT].copy(),
        env_success=bool(info["is_success"]),
        held=bool(info["index_contact"] and info["thumb_contact"]),
        skill_start=float(u.skill_start if u.skill_start is not None else 0.0),
        intervention=float(np.mean(offsets)) / mean_motion if mean_motion > 0 else 0.0,
        top_skill=top,
        pinched=np.asarray(pinched, dtype=bool),
    )
    if getattr(u, "switch_to", None) is not None:
        result.switch_latency_s = intent_latency(
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
    ``reference``'s from the reference's skill start ``t_s`` to the end, at the time shift
    of at most :data:`MAX_TIME_SHIFT` that fits best (``inf`` if ``result`` ended early).

    The motion is the skill's, relative to the pen's pose where it starts (as skill transfer
    reads a skill: :mod:`ias_gym.skills.transfer`): the centre's displacement
    ``p(t) - p(t_s)`` and the axis' change ``a(t) - a(t_s)`` (a chord of the unit sphere:
    the axis' rotation angle for small angles, with its direction). ``result`` is read from
    ``t_s + k dt`` against the reference from ``t_s`` for every whole-step shift
    ``|k dt| <= MAX_TIME_SHIFT``, over the steps both sessions have; the shift with the
    smallest ``max(dp / POSITION_TOLERANCE, da / ROTATION_TOLERANCE)`` counts, so a session
    is within both tolerances exactly when it is at some shift. A session
    done a little early or late is the skill done (a 100 ms lag only delays an operator who
    does not close a loop through it).
    """
    n = len(reference.times)
    if len(result.times) < n:
        return math.inf, math.inf
    start = int(np.searchsorted(reference.times, reference.skill_start))
    dt = float(reference.times[1] - reference.times[0]) if n > 1 else 1.0
    most = round(MAX_TIME_SHIFT / dt)
    axis_ref, axis_res = pen_axis(reference.pen_quat), pen_axis(result.pen_quat)
    best = (math.inf, math.inf, math.inf)
    for k in range(-min(most, start), most + 1):
        end = n - max(k, 0)  # reference steps [start, end) against result [start+k, end+k)
        if end - start < 2:
            continue
        p0 = reference.pen_position[start:end] - reference.pen_position[start]
        p1 = result.pen_position[start + k : end + k] - result.pen_position[start + k]
        a0 = axis_ref[start:end] - axis_ref[start]
        a1 = axis_res[start + k : end + k] - axis_res[start + k]
        dp = float(np.sqrt(np.mean(np.sum((p1 - p0) ** 2, axis=1))))
        da = float(np.sqrt(np.mean(np.sum((a1 - a0) ** 2, axis=1))))
        score = max(dp / POSITION_TOLERANCE, da / ROTATION_TOLERANCE)
        if score < best[0]:
            best = (score, dp, da)
    return best[1], best[2]


def session_success(result: SessionResult, reference: SessionResult) -> bool:
    """Judge ``result`` against the unimpaired ``reference`` (module docstring); also sets
    ``result.success``."""
    dp, dr = pose_errors(result, reference)
    ok = (
        result.env_success and result.held and dp <= POSITION_TOLERANCE and dr <= ROTATION_TOLERANCE
    )
    result.success = bool(ok)
    return result.success


def session_record(result: SessionResult, reference: SessionResult) -> dict[str, Any]:
    """What a table keeps of one judged session: success, the env's success, whether the pen
    is held at the end, the first step from the lift on with a pad off it, the pose errors
    against ``reference`` (None where infinite: the session ended early), and the pen's height
    at the lift's end (:data:`LIFT_END`) less the reference's [mm] (None if either ended
    before it): a pinch that holds the pen lower in the hand lifts it less, which the pose
    errors, counted from the skill's start, do not see."""
    dp, da = pose_errors(result, reference)
    pinched = np.asarray(result.pinched, dtype=bool)
    off = np.flatnonzero(~pinched & (result.times >= HELD_FROM - 1e-9))

    def lift_height(session: SessionResult) -> float | None:
        at = np.flatnonzero(session.times >= LIFT_END - 1e-9)
        return float(session.pen_position[at[0], 2]) if at.size else None

    z, z_ref = lift_height(result), lift_height(reference)
    return {
        "success": session_success(result, reference),
        "env_success": result.env_success,
        "held_at_end": result.held,
        "pad_off_from_s": float(result.times[off[0]]) if off.size else None,
        "position_error_mm": 1e3 * dp if math.isfinite(dp) else None,
        "axis_error_deg": math.degrees(da) if math.isfinite(da) else None,
        "intervention": result.intervention,
        "lift_height_error_mm": None if z is None or z_ref is None else 1e3 * (z - z_ref),
    }

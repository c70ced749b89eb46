"""How a recogniser follows an operator who changes their mind (paper Flow 3).

The operator performs one skill until a switch time, then another (``IAS-GloveAssist-v0``'s
``switch_to``, ``switch_time``: the second skill's motion at the phase it has then, blended
in over 0.2 s). A switch is **followed** when the recogniser's most probable name is the
second skill from some time after the switch to the end of the session; the **latency** is
that time less the switch time (:func:`~ias_gym.assist.sessions.intent_latency`), reported
as the median over the switches followed.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ias_gym.assist.metrics import posterior_trace
from ias_gym.assist.recognition import Recogniser
from ias_gym.assist.stream import SessionFrame
from ias_gym.errors import InputError
from ias_gym.rates import Rate

#: (from, to) skill pairs of the intent-switch measurement, and the episode time [s] of the
#: switch: about 0.4 s into the first skill's motion, so that the second's motion is still
#: under way.
SWITCH_PAIRS: tuple[tuple[str, str], ...] = (
    ("lift_hold", "tilt_left"),
    ("seesaw_slow", "tilt_right"),
    ("tilt_left", "lift_place"),
)
SWITCH_TIME = 2.2


@dataclass(frozen=True, eq=False)
class SwitchSession:
    """A glove session in which the operator changes their mind.

    Attributes:
        person_id: who performed it.
        first, second: the skill performed until ``switch_time``, and the one after.
        switch_time: episode time of the switch [s].
        frames: its frames from reset on.
    """

    person_id: str
    first: str
    second: str
    switch_time: float
    frames: list[SessionFrame]


def record_switch_sessions(
    jobs: Sequence[tuple[str, str, str, float]],
    seed: int = 0,
    progress: Callable[[Iterable[Any]], Iterable[Any]] | None = None,
) -> list[SwitchSession]:
    """Record unimpaired sessions of ``IAS-GloveAssist-v0`` with an intent switch and no
    assistant (the env's ``switch_to``, ``switch_time``).

    Args:
        jobs: ``(person, first skill, second skill, switch time [s])`` each.
        seed: the reset seed.
        progress: wraps the jobs (e.g. ``tqdm``).

    Raises:
        InputError: an unknown skill, an invalid person id or a negative switch time.
    """
    import gymnasium as gym

    import ias_gym  # noqa: F401 - registers the envs
    from ias_gym.assist.stream import record_session

    out = []
    for person, first, second, t in progress(jobs) if progress else jobs:
        env = gym.make(
            "IAS-GloveAssist-v0", person_id=person, skill=first, switch_to=second, switch_time=t
        )
        try:
            _, frames = record_session(env, seed=seed)
        finally:
            env.close()
        out.append(SwitchSession(person, first, second, float(t), frames))
    return out


def evaluate_switches(recogniser: Recogniser, sessions: Sequence[SwitchSession]) -> dict[str, Any]:
    """How a recogniser follows intent switches, frame by frame.

    Returns:
        ``switches``, ``switches_followed`` (the share followed, and under ``rates`` with its
        95 % Wilson interval), ``switch_latency_s`` (the median latency [s] of those
        followed, or ``None``) and ``switch_latencies_s`` (each session's, ``None`` where not
        followed).

    Raises:
        InputError: no sessions.
    """
    from ias_gym.assist.sessions import intent_latency

    if not sessions:
        raise InputError("no switch sessions to evaluate")
    latencies: list[float | None] = []
    for s in sessions:
        P, names, times = posterior_trace(recogniser, s.frames)
        top = [names[int(i)] for i in np.argmax(P, axis=1)]
        latency = intent_latency(times, top, s.second, s.switch_time)
        latencies.append(latency if np.isfinite(latency) else None)
    followed = [x for x in latencies if x is not None]
    rate = Rate.of([x is not None for x in latencies])
    return {
        "switches": len(sessions),
        "switches_followed": rate.value,
        "switch_latency_s": float(np.median(followed)) if followed else None,
        "switch_latencies_s": latencies,
        "rates": {"switches_followed": rate.to_dict()},
    }

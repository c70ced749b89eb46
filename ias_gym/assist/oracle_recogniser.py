"""The oracle recogniser: the true intent, with the recogniser protocol.

:class:`OracleRecogniser` is the upper bound a learned recogniser is compared with and the
analytic assistant's default: it names the skill the env says the operator intends.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from ias_gym.glove.skills import SKILLS


class OracleRecogniser:
    """A recogniser that knows the intent (the protocol of :mod:`ias_gym.assist.recognition`).

    Args:
        intent: episode time [s] -> the intended skill (e.g. the env's ``intent``).
        skills: the skills it names.
    """

    def __init__(self, intent: Callable[[float], str], skills: Sequence[str] = SKILLS) -> None:
        self.intent = intent
        self._skills = tuple(skills)

    @property
    def skills(self) -> tuple[str, ...]:
        """The skills it knows."""
        return self._skills

    def reset(self) -> None:
        """Nothing to forget."""

    def update(self, frame: Any) -> dict[str, float]:
        """Posterior 1 on the intent at ``frame.time_s`` (``"unknown"`` if not a known skill)."""
        truth = self.intent(float(frame.time_s))
        post = dict.fromkeys((*self._skills, "unknown"), 0.0)
        post[truth if truth in self._skills else "unknown"] = 1.0
        return post

    def add_skill(self, name: str, sessions: Sequence[Sequence[Any]]) -> None:
        """Know ``name`` from now on (the oracle needs no sessions)."""
        if name not in self._skills:
            self._skills = (*self._skills, name)

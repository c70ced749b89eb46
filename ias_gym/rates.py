"""Success rates as every table reports them: a rate with its 95 % Wilson interval, and what set
it was measured on.

Every success figure in the README and the docs is measured on persons (or seeds) drawn by a
seed at evaluation time, at least :data:`MIN_PERSONS` of them, and reported as a
:class:`Rate`: successes of trials with the Wilson score interval (Wilson 1927; Brown, Cai &
DasGupta, Statist. Sci. 16, 2001, recommend it over the normal interval for small n and
rates near 0 or 1). A table also says whether its set is *development* data (the methods
were tuned on it or after seeing it) or *held-out* (drawn after the last change, run once).
Pure Python.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from ias_gym.errors import InputError

#: Fewest persons (or seeds) per row of a reported table.
MIN_PERSONS = 30
#: z of a two-sided 95 % interval.
Z95 = 1.959963984540054

SetKind = Literal["development", "held-out"]
SET_KINDS: tuple[str, ...] = ("development", "held-out")


def wilson_interval(successes: int, trials: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of a binomial rate ``successes / trials``.

    Args:
        successes: how many trials succeeded (0 <= successes <= trials).
        trials: how many trials (>= 1).
        z: the normal quantile of the interval's level (default 95 %, two-sided).

    Returns:
        ``(low, high)`` in [0, 1].

    Raises:
        InputError: counts that are not whole, negative, or successes > trials.
    """
    if trials < 1 or successes < 0 or successes > trials:
        raise InputError(
            f"a rate needs 0 <= successes <= trials, trials >= 1; got {successes}/{trials}"
        )
    p = successes / trials
    z2 = z * z
    centre = (p + z2 / (2 * trials)) / (1 + z2 / trials)
    half = z * math.sqrt(p * (1 - p) / trials + z2 / (4 * trials * trials)) / (1 + z2 / trials)
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == trials else min(1.0, centre + half)
    return low, high


@dataclass(frozen=True)
class Rate:
    """A success rate with its 95 % Wilson interval.

    Attributes:
        successes: successful trials.
        trials: all trials.
    """

    successes: int
    trials: int

    def __post_init__(self) -> None:
        wilson_interval(self.successes, self.trials)  # checks the counts

    @classmethod
    def of(cls, outcomes: list[bool] | tuple[bool, ...]) -> Rate:
        """The rate of a list of outcomes.

        Raises:
            InputError: no outcomes.
        """
        return cls(sum(bool(o) for o in outcomes), len(outcomes))

    @property
    def value(self) -> float:
        """successes / trials (-)."""
        return self.successes / self.trials

    @property
    def interval(self) -> tuple[float, float]:
        """The 95 % Wilson interval (low, high) (-)."""
        return wilson_interval(self.successes, self.trials)

    def to_dict(self) -> dict[str, float | int]:
        """JSON fields: ``success_rate``, ``ci95_low``, ``ci95_high``, ``successes``,
        ``trials``."""
        low, high = self.interval
        return {
            "success_rate": self.value,
            "ci95_low": low,
            "ci95_high": high,
            "successes": self.successes,
            "trials": self.trials,
        }

    def __str__(self) -> str:
        low, high = self.interval
        counts = f"{self.successes}/{self.trials}"
        return f"{self.percent} % [{100 * low:.0f}, {100 * high:.0f}] ({counts})"

    @property
    def percent(self) -> str:
        """The rate in percent, whole unless that would read as all or none when it is not
        (199 of 200 is ``99.5``, not ``100``)."""
        pct = 100 * self.value
        for digits in range(4):
            text = f"{pct:.{digits}f}"
            if float(text) not in (0.0, 100.0) or pct in (0.0, 100.0):
                return text
        return text


def rate_json(outcomes: list[bool] | tuple[bool, ...]) -> dict[str, float | int] | None:
    """:meth:`Rate.to_dict` of the outcomes, or None without any (a row nobody was judged in)."""
    return Rate.of(outcomes).to_dict() if outcomes else None


def check_set_kind(kind: str) -> str:
    """``kind`` if it is ``"development"`` or ``"held-out"``.

    Raises:
        InputError: anything else.
    """
    if kind not in SET_KINDS:
        raise InputError(f"set kind {kind!r} must be one of {', '.join(SET_KINDS)}")
    return kind

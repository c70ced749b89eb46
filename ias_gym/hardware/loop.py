"""Pacing a host loop in real time, and its statistics.

CPython is not hard real time (DESIGN.md: about 1 kHz on average, p99 about 2 ms for a
plain loop): :class:`LoopClock` paces against absolute deadlines (a late cycle does not
shift the ones after it; a cycle more than one period late re-synchronises instead of
bursting) and records when each cycle started, so that :func:`loop_stats` can report the
distribution, never assert single cycles.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np

#: A period longer than this many nominal periods counts as an overrun.
OVERRUN_FACTOR = 1.5


class LoopClock:
    """Deadlines every ``period`` [s]; :meth:`wait` sleeps until the next one."""

    def __init__(self, period: float) -> None:
        if not period > 0:
            raise ValueError(f"period must be positive [s], got {period}")
        self.period = float(period)
        self.starts: list[float] = []
        self._deadline = time.perf_counter()

    def restart(self) -> None:
        """The next deadline is one period from now; forget the recorded starts."""
        self._deadline = time.perf_counter()
        self.starts = []

    def wait(self) -> float:
        """Sleep until the next deadline; return the time the cycle starts (perf_counter)."""
        self._deadline += self.period
        now = time.perf_counter()
        if now < self._deadline:
            time.sleep(self._deadline - now)
        elif now - self._deadline > self.period:
            self._deadline = now  # hopelessly late: start afresh rather than burst
        start = time.perf_counter()
        self.starts.append(start)
        return start


@dataclass(frozen=True)
class LoopStats:
    """Statistics of a paced loop (the ``ias-gym glove-bench --json`` keys).

    Attributes:
        rate_hz: cycles per second, over the whole run.
        period_median_ms, period_p99_ms, period_max_ms: cycle start to cycle start [ms].
        overrun_fraction: share of periods longer than :data:`OVERRUN_FACTOR` x nominal.
        frames_dropped: sensor frames the host missed (counter gaps).
        watchdog_trips: host-side watchdog trips.
        cycles: cycles measured.
    """

    rate_hz: float
    period_median_ms: float
    period_p99_ms: float
    period_max_ms: float
    overrun_fraction: float
    frames_dropped: int
    watchdog_trips: int
    cycles: int

    def as_dict(self) -> dict[str, float | int]:
        """The statistics as a plain dict."""
        return asdict(self)


def loop_stats(
    starts: list[float], period: float, frames_dropped: int = 0, watchdog_trips: int = 0
) -> LoopStats:
    """Statistics of cycle start times ``starts`` [s] for a nominal ``period`` [s].

    Raises:
        ValueError: fewer than two cycles.
    """
    if len(starts) < 2:
        raise ValueError(f"need at least two cycles to measure periods, got {len(starts)}")
    t = np.asarray(starts)
    periods = np.diff(t)
    return LoopStats(
        rate_hz=float(len(periods) / (t[-1] - t[0])),
        period_median_ms=float(np.median(periods) * 1e3),
        period_p99_ms=float(np.percentile(periods, 99) * 1e3),
        period_max_ms=float(periods.max() * 1e3),
        overrun_fraction=float(np.mean(periods > OVERRUN_FACTOR * period)),
        frames_dropped=int(frames_dropped),
        watchdog_trips=int(watchdog_trips),
        cycles=len(periods),
    )

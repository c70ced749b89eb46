"""Pacing a host loop in real time, and its statistics.

CPython is not hard real time (docs/DESIGN.md: about 1 kHz on average, p99 about 2 ms for a
plain loop): :class:`LoopClock` paces against absolute deadlines (a late cycle does not
shift the ones after it; a cycle more than one period late re-synchronises instead of
bursting) and records when each cycle started, so that :func:`loop_stats` can report the
distribution, never assert single cycles.
"""

from __future__ import annotations

import contextlib
import math
import os
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass

import numpy as np

from ias_gym.errors import InputError

#: A period longer than this many nominal periods counts as an overrun.
OVERRUN_FACTOR = 1.5
#: The virtual world's time step [s]: a host loop's period is a whole number of them.
WORLD_STEP = 0.001


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


@contextlib.contextmanager
def realtime_priority(priority: int | None) -> Iterator[None]:
    """Run the calling thread under Linux's ``SCHED_FIFO`` at ``priority`` (None: unchanged).

    Threads started inside inherit it (the glove's receiver, an in-process emulator), so a
    loop and its helpers all run ahead of the machine's ordinary processes; the thread's
    previous policy comes back on exit. On a loaded machine this is what keeps a 1 kHz
    CPython loop on time (measured in docs/can-protocol.md); it needs root,
    ``CAP_SYS_NICE`` or an ``ulimit -r`` of at least ``priority``.

    Args:
        priority: 1 (lowest) to 99 (highest) real-time priority, or None.

    Raises:
        InputError: a priority out of range, no ``SCHED_FIFO`` on this system, or not
            permitted (the message says what grants it).
    """
    if priority is None:
        yield
        return
    if not hasattr(os, "sched_setscheduler"):
        raise InputError("--priority needs Linux's SCHED_FIFO; leave it out on this system")
    lo, hi = os.sched_get_priority_min(os.SCHED_FIFO), os.sched_get_priority_max(os.SCHED_FIFO)
    if not lo <= priority <= hi:
        raise InputError(f"--priority must be {lo} to {hi} (SCHED_FIFO), got {priority}")
    policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except PermissionError as e:
        raise InputError(
            f"--priority {priority}: SCHED_FIFO is not permitted ({e}); run as root, give "
            "python CAP_SYS_NICE, or raise the rtprio limit (ulimit -r), or leave it out"
        ) from e
    try:
        yield
    finally:
        os.sched_setscheduler(0, policy, param)


def check_bench_numbers(rate_hz: float, seconds: float, repeats: int = 1) -> None:
    """Check a bench's numbers before anything is opened.

    Raises:
        InputError: a rate [Hz] that is not positive or whose period is not a whole number
            of the world's 1 ms steps (1000, 500, 250, ... Hz), a non-positive or infinite
            ``seconds`` [s], or fewer than one run; or too short a run for two cycles.
    """
    if not 0 < rate_hz < math.inf:
        raise InputError(f"--rate must be a positive number of Hz, got {rate_hz:g}")
    steps = 1.0 / (rate_hz * WORLD_STEP)
    if steps < 1 - 1e-9 or abs(steps - round(steps)) > 1e-6:
        raise InputError(
            f"--rate {rate_hz:g} Hz: the period must be a whole number of the world's "
            f"{WORLD_STEP * 1e3:g} ms steps (1000, 500, 250, 200, ... Hz)"
        )
    if not 0 < seconds < math.inf:
        raise InputError(f"--seconds must be a positive number of seconds, got {seconds:g}")
    if round(seconds * rate_hz) < 2:
        raise InputError(
            f"--seconds {seconds:g} at {rate_hz:g} Hz is fewer than two cycles; run longer"
        )
    if repeats < 1:
        raise InputError(f"--repeats must be at least 1, got {repeats}")

"""``ias-gym glove-bench``: the host loop against the glove (or its emulator), measured beside
a plain python-can loop in the same run.

The host loop is IAS-GloveHardware-v0's step at ``control_dt = 1 / rate``: wait for the
deadline, read the newest sample, calibrate it, step the virtual world, send the force
display. The plain loop is what python-can and CPython give by themselves: the same
absolute-deadline pacing (:class:`~ias_gym.hardware.loop.LoopClock`), drain the received
frames, send one zero-torque command, nothing else. Both run against the same glove: on the
virtual bus a :class:`~ias_gym.hardware.emulator.GloveEmulator` in this process (python-can's
virtual bus does not leave the process), sampling at the same rate. A machine's load moves
both loops, so the figure to compare across runs and machines is the ratio of their p99
periods measured in one invocation (runs alternate plain, host, plain, host, ...).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from ias_gym.glove.device import ACTUATED_JOINTS
from ias_gym.glove.hand import JOINT_NAMES
from ias_gym.hardware.can_glove import CanGlove, check_interface, open_bus, to_message
from ias_gym.hardware.emulator import GloveEmulator
from ias_gym.hardware.env import GloveHardwareEnv
from ias_gym.hardware.loop import (
    LoopClock,
    LoopStats,
    check_bench_numbers,
    loop_stats,
    realtime_priority,
)
from ias_gym.hardware.protocol import encode_torque

T = TypeVar("T")


@dataclass(frozen=True)
class BenchResult:
    """A glove-bench invocation: the host loop's statistics, the plain loop's beside them.

    Attributes:
        stats: the host loop (:class:`~ias_gym.hardware.loop.LoopStats`; over several runs,
            each figure is the median of the runs', counts are summed).
        plain: the plain python-can loop, the same way (None if it was not run).
        p99_ratio: host p99 period / plain p99 period, the median over the runs' pairs
            (None without the plain loop).
        step_median_ms: median time from cycle start to the force display sent [ms].
        sample_age_median: median age of the sample a command was computed from, in glove
            samples (emulator side; None without the in-process emulator).
        runs: runs per loop.
        priority: the SCHED_FIFO priority both loops ran at (None: the default scheduler).
    """

    stats: LoopStats
    plain: LoopStats | None
    p99_ratio: float | None
    step_median_ms: float
    sample_age_median: float | None
    runs: int = 1
    priority: int | None = None

    def as_dict(self) -> dict[str, Any]:
        """All numbers as one flat dict (the host loop's keys first, then ``plain_*``)."""
        out: dict[str, Any] = {
            **self.stats.as_dict(),
            "step_median_ms": self.step_median_ms,
            "sample_age_median": self.sample_age_median,
        }
        if self.plain is not None:
            out["plain_p99_ms"] = self.plain.period_p99_ms
            out["plain_overrun_fraction"] = self.plain.overrun_fraction
            out["plain_period_median_ms"] = self.plain.period_median_ms
            out["p99_ratio"] = self.p99_ratio
        out["runs"] = self.runs
        out["priority"] = self.priority
        return out


def run_plain_loop(
    interface: str = "virtual",
    channel: str | int = "ias-glove-bench",
    *,
    rate_hz: float = 1000.0,
    seconds: float = 5.0,
    fd: bool = False,
    bus_kwargs: dict[str, Any] | None = None,
) -> LoopStats:
    """The plain python-can loop for ``seconds`` [s] at ``rate_hz`` [Hz]: paced like the host
    loop, each cycle drains the received frames and sends one zero-torque command (the glove
    is never enabled, so a real one applies no torque).

    Raises:
        InputError: the bus cannot be opened.
    """
    kwargs = dict(bus_kwargs or {})
    if fd:
        kwargs.setdefault("fd", True)
    bus = open_bus(interface, channel, **kwargs)
    try:
        while bus.recv(timeout=0.0) is not None:  # what came before the first cycle
            pass
        clock = LoopClock(1.0 / rate_hz)
        zero = np.zeros(len(ACTUATED_JOINTS))
        for k in range(round(seconds * rate_hz)):
            clock.wait()
            while bus.recv(timeout=0.0) is not None:
                pass
            frame = encode_torque(zero, k + 1, k, fd=fd)[0]
            try:
                bus.send(to_message(frame), timeout=0.001)
            except Exception:  # a full queue: the host loop counts these too, never stops
                pass
        return loop_stats(clock.starts, clock.period)
    finally:
        bus.shutdown()


def _run_host_loop(
    interface: str,
    channel: str | int,
    rate_hz: float,
    seconds: float,
    fd: bool,
    bus_kwargs: dict[str, Any] | None,
) -> tuple[LoopStats, float]:
    """IAS-GloveHardware-v0's host loop; its statistics and the median step time [ms]."""
    period = 1.0 / rate_hz
    env = GloveHardwareEnv(
        interface=interface,
        channel=channel,
        fd=fd,
        bus_kwargs=bus_kwargs,
        control_dt=period,
        duration=seconds + 1.0,
    )
    try:
        env.reset(seed=0)
        action = np.zeros(len(JOINT_NAMES), dtype=np.float32)
        busy = []
        for _ in range(round(seconds * rate_hz)):
            _, _, _, _, info = env.step(action)
            busy.append(time.perf_counter() - env.clock.starts[-1])
            if info["fault"]:
                env.device.enable()  # counted in watchdog_trips; keep measuring
        device = env.device
        assert isinstance(device, CanGlove)  # a live env's device (not a replay)
        stats = loop_stats(
            env.clock.starts,
            period,
            frames_dropped=device.stats.frames_dropped,
            watchdog_trips=device.watchdog_trips,
        )
    finally:
        env.close()
    return stats, float(np.median(busy) * 1e3)


def _combine(runs: list[LoopStats]) -> LoopStats:
    """One LoopStats for several runs: medians of the figures, sums of the counts."""

    def median(name: str) -> float:
        return float(np.median([getattr(r, name) for r in runs]))

    return LoopStats(
        rate_hz=median("rate_hz"),
        period_median_ms=median("period_median_ms"),
        period_p99_ms=median("period_p99_ms"),
        period_max_ms=median("period_max_ms"),
        overrun_fraction=median("overrun_fraction"),
        frames_dropped=sum(r.frames_dropped for r in runs),
        watchdog_trips=sum(r.watchdog_trips for r in runs),
        cycles=sum(r.cycles for r in runs),
    )


def run_glove_bench(
    interface: str = "virtual",
    channel: str | int = "ias-glove-bench",
    *,
    rate_hz: float = 1000.0,
    seconds: float = 5.0,
    fd: bool = False,
    emulate: bool | None = None,
    bus_kwargs: dict[str, Any] | None = None,
    plain: bool = True,
    repeats: int = 1,
    priority: int | None = None,
) -> BenchResult:
    """Run the host loop (and the plain loop beside it) for ``seconds`` [s] at ``rate_hz``
    [Hz], ``repeats`` times each, alternating, and measure them.

    Args:
        interface, channel, bus_kwargs: the bus.
        rate_hz: loop rate [Hz]; ``1 / rate_hz`` must be a multiple of the world's 1 ms step.
        seconds: how long each run lasts [s].
        fd: CAN FD sensor frames.
        emulate: run a :class:`GloveEmulator` in this process for each run (default: on the
            virtual bus).
        plain: also run the plain python-can loop (:func:`run_plain_loop`).
        repeats: runs per loop (the result holds medians).
        priority: run both loops (and the threads they start) under SCHED_FIFO at this
            priority (:func:`~ias_gym.hardware.loop.realtime_priority`).

    Raises:
        InputError: numbers refused by :func:`check_bench_numbers`, an unknown interface, a
            bus that cannot be opened, or a priority that is not permitted.
        ~ias_gym.hardware.can_glove.GloveTimeoutError: no glove answers on the bus.
    """
    check_bench_numbers(rate_hz, seconds, repeats)
    check_interface(interface)
    emulate = interface == "virtual" if emulate is None else emulate

    def with_glove(run: Callable[[], T]) -> tuple[T, GloveEmulator | None]:
        """``run()`` against a fresh emulator (if any), both at ``priority``."""
        with realtime_priority(priority):  # before the emulator's thread starts: it inherits
            if not emulate:
                return run(), None
            kwargs = bus_kwargs or {}
            with GloveEmulator(interface, channel, rate_hz=rate_hz, fd=fd, **kwargs) as emulator:
                return run(), emulator

    hosts: list[LoopStats] = []
    plains: list[LoopStats] = []
    steps: list[float] = []
    ages: list[int] = []
    for _ in range(repeats):
        if plain:
            stats, _ = with_glove(
                lambda: run_plain_loop(
                    interface,
                    channel,
                    rate_hz=rate_hz,
                    seconds=seconds,
                    fd=fd,
                    bus_kwargs=bus_kwargs,
                )
            )
            plains.append(stats)
        (stats, step), emulator = with_glove(
            lambda: _run_host_loop(interface, channel, rate_hz, seconds, fd, bus_kwargs)
        )
        hosts.append(stats)
        steps.append(step)
        if emulator is not None:
            ages.extend(emulator.command_age)
    ratio = (
        float(
            np.median(
                [h.period_p99_ms / p.period_p99_ms for h, p in zip(hosts, plains, strict=True)]
            )
        )
        if plains
        else None
    )
    return BenchResult(
        stats=_combine(hosts),
        plain=_combine(plains) if plains else None,
        p99_ratio=ratio,
        step_median_ms=float(np.median(steps)),
        sample_age_median=float(np.median(ages)) if ages else None,
        runs=repeats,
        priority=priority,
    )

"""``ias-gym glove-bench``: the host loop against the glove (or its emulator), measured.

The host loop is IAS-GloveHardware-v0's step at ``control_dt = 1 / rate``: wait for the
deadline, read the newest sample, calibrate it, step the virtual world, send the force
display. On the virtual bus the :class:`~ias_gym.hardware.emulator.GloveEmulator` runs in
this process (python-can's virtual bus does not leave the process), sampling at the same
rate.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from ias_gym.glove.hand import JOINT_NAMES
from ias_gym.hardware.can_glove import CanGlove
from ias_gym.hardware.emulator import GloveEmulator
from ias_gym.hardware.env import GloveHardwareEnv
from ias_gym.hardware.loop import LoopStats, loop_stats


@dataclass(frozen=True)
class BenchResult:
    """A glove-bench run: the loop statistics and what else was measured.

    Attributes:
        stats: the JSON keys (:class:`~ias_gym.hardware.loop.LoopStats`).
        step_median_ms: median time from cycle start to the force display sent [ms].
        sample_age_median: median age of the sample a command was computed from, in glove
            samples (emulator side; None without the in-process emulator).
    """

    stats: LoopStats
    step_median_ms: float
    sample_age_median: float | None

    def as_dict(self) -> dict[str, Any]:
        """All numbers as one flat dict (the stats' keys first)."""
        return {
            **self.stats.as_dict(),
            "step_median_ms": self.step_median_ms,
            "sample_age_median": self.sample_age_median,
        }


def run_glove_bench(
    interface: str = "virtual",
    channel: str | int = "ias-glove-bench",
    *,
    rate_hz: float = 1000.0,
    seconds: float = 5.0,
    fd: bool = False,
    emulate: bool | None = None,
    bus_kwargs: dict[str, Any] | None = None,
) -> BenchResult:
    """Run the host loop for ``seconds`` [s] at ``rate_hz`` [Hz] and measure it.

    Args:
        interface, channel, bus_kwargs: the bus.
        rate_hz: loop rate [Hz]; ``1 / rate_hz`` must be a multiple of the world's 1 ms step.
        seconds: how long to run [s].
        fd: CAN FD sensor frames.
        emulate: run a :class:`GloveEmulator` in this process (default: on the virtual bus).

    Raises:
        ValueError: a rate whose period is not a multiple of 1 ms, or a non-positive time.
    """
    if not seconds > 0:
        raise ValueError(f"seconds must be positive, got {seconds}")
    emulate = interface == "virtual" if emulate is None else emulate
    period = 1.0 / rate_hz
    emulator = (
        GloveEmulator(interface, channel, rate_hz=rate_hz, fd=fd, **(bus_kwargs or {}))
        if emulate
        else None
    )
    try:
        if emulator is not None:
            emulator.start()
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
    finally:
        if emulator is not None:
            emulator.close()
    age = (
        float(np.median(emulator.command_age))
        if emulator is not None and emulator.command_age
        else None
    )
    return BenchResult(stats, float(np.median(busy) * 1e3), age)

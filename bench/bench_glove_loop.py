"""The glove's host loop on python-can's virtual bus at 500 Hz and 1 kHz, and the bus load.

Run: ``python bench/bench_glove_loop.py [--seconds 10] [--repeats 3] [--priority 10]
[--json FILE]``. Against the in-process :class:`~ias_gym.hardware.GloveEmulator`, side by
side in this one run (:func:`~ias_gym.hardware.bench.run_glove_bench`, the runs
alternating):

1. *plain python-can loop*: drain the received frames, encode and send one torque command,
   sleep to the next deadline (no decoding, no calibration, no world): what python-can and
   CPython give by themselves;
2. *host loop*: IAS-GloveHardware-v0's step (newest sample -> calibration -> world step ->
   force display) with the CanGlove's receiver thread and watchdog;
3. *world only*: the same env step paced the same way, on a glove that hands back one fixed
   reading (no bus, no emulator, no threads): what the host's own work costs.

``--priority P`` runs all three (and their threads) under SCHED_FIFO at priority P, and
``--load N`` starts N busy Python processes for the whole run (the "loaded" rows of the
table in docs/can-protocol.md: each spins on one core's worth of work, as the machine's
other users would).

Then the host watchdog: ``--silences`` times the emulator goes quiet for 100 ms at 1 kHz, and
the time from the last valid sample to the trip is measured.

The first table gives per loop and rate the medians over ``--repeats`` runs of: period
median / p99 / max [ms], overrun fraction (periods > 1.5 x nominal), frames dropped,
watchdog trips; then the goal per rate on the ratios host / plain of the p99 period (the
median of the runs' pairs, <= 1.15) and of the overrun fraction (<= 1.5). Then the
watchdog's trip delay (median, max), and the protocol's bus load at each rate (classic CAN
1 Mbit/s; CAN FD 1/5 Mbit/s).
"""

from __future__ import annotations

import argparse
import itertools
import platform
import subprocess
import sys
import time

import can
import numpy as np
from numpy.typing import ArrayLike
from report import Report

from ias_gym.envs.glove_grasp import GloveGraspEnv
from ias_gym.glove.device import ACTUATED_JOINTS, GloveDevice, GloveReading
from ias_gym.glove.hand import PersonParams
from ias_gym.glove.operator import FromPreShape
from ias_gym.glove.sensor_model import sensor_readings
from ias_gym.hardware import CanGlove, GloveEmulator, LoopClock, bus_load
from ias_gym.hardware.bench import run_glove_bench
from ias_gym.hardware.loop import LoopStats, loop_stats, realtime_priority
from ias_gym.hardware.protocol import encode_torque
from ias_gym.sim.glove_scene import scene_operator

GOAL_P99_RATIO = 1.15
GOAL_OVERRUN_RATIO = 1.5
_channels = itertools.count()


class FixedGlove(GloveDevice):
    """A glove that returns one reading for ever and ignores the force display."""

    glove_id = "fixed"

    def __init__(self, psi: np.ndarray) -> None:
        self.psi = psi

    @property
    def n_actuators(self) -> int:
        return len(ACTUATED_JOINTS)

    def read(self) -> GloveReading:
        return GloveReading(psi=self.psi.copy(), timestamp=0.0)

    def write_feedback(self, torques: ArrayLike) -> None:
        encode_torque(torques, 1, 0)  # the encoding the CAN glove would do

    def close(self) -> None:
        pass


def world_loop(rate_hz: float, seconds: float) -> LoopStats:
    """The env step of the host loop, paced by a LoopClock, without bus or threads."""
    person = PersonParams.sample("p1")  # the emulator's default wearer, holding the pinch
    psi = sensor_readings(FromPreShape(scene_operator(person))(1.0), person)
    period = 1.0 / rate_hz
    env = GloveGraspEnv(
        control_dt=period, duration=seconds + 1.0, glove_factory=lambda seed: FixedGlove(psi)
    )
    env.reset(seed=0)
    clock = LoopClock(period)
    shape = env.action_space.shape
    assert shape is not None
    action = np.zeros(shape, dtype=np.float32)
    for _ in range(round(seconds * rate_hz)):
        clock.wait()
        env.step(action)
    env.close()
    return loop_stats(clock.starts, period)


def watchdog_delays(silences: int) -> np.ndarray:
    """Time from the last valid sample to the host watchdog's trip [ms], per silence."""
    channel = f"bench-watchdog-{next(_channels)}"
    delays = []
    with GloveEmulator(channel=channel, rate_hz=1000.0) as emu, CanGlove(channel=channel) as glove:
        glove.read()
        for _ in range(silences):
            glove.enable()
            glove.wait_for_sample()
            time.sleep(0.05)
            emu.pause(0.1)
            time.sleep(0.15)
            delays.append(glove.trip_delays[-1] * 1e3)
    return np.array(delays)


def busy_load(n: int) -> list[subprocess.Popen[bytes]]:
    """``n`` processes that spin in Python for ever (killed by the caller)."""
    spin = "while True: pass"
    return [subprocess.Popen([sys.executable, "-c", spin]) for _ in range(n)]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="per run [s]")
    parser.add_argument("--repeats", type=int, default=3, help="runs per loop and rate")
    parser.add_argument("--silences", type=int, default=20, help="watchdog trips to time")
    parser.add_argument("--priority", type=int, help="SCHED_FIFO priority of the loops")
    parser.add_argument("--load", type=int, default=0, help="busy processes during the run")
    parser.add_argument("--rates", default="500,1000", help="comma-separated loop rates [Hz]")
    report, args = Report.start(parser)
    report.note(
        f"{platform.python_implementation()} {platform.python_version()}, python-can "
        f"{can.__version__}"
    )
    load = busy_load(args.load)
    try:
        run(args, report)
    finally:
        for process in load:
            process.kill()
            process.wait()
    report.finish()
    return 0


def run(args: argparse.Namespace, report: Report) -> None:
    """The loops' table and goals, the watchdog delays and the bus load."""
    fields = ("period_median_ms", "period_p99_ms", "period_max_ms", "overrun_fraction")
    rates = [float(r) for r in args.rates.split(",")]
    priority = f"priority {args.priority}" if args.priority else "default priority"
    table = report.table(
        "The glove's host loop against a plain python-can loop at the same rate, on "
        "python-can's virtual bus with the in-process emulator, runs alternating, and the "
        f"world's env step alone on a fixed reading; medians of {args.repeats} runs of "
        f"{args.seconds:g} s per loop and rate, {priority}, {args.load} busy processes; "
        "overrun: a period > 1.5 x nominal",
        [
            "loop",
            "rate [Hz]",
            "period median [ms]",
            "period p99 [ms]",
            "period max [ms]",
            "overrun fraction",
            "frames dropped",
            "watchdog trips",
        ],
    )

    def row(name: str, rate: float, stats: LoopStats) -> None:
        values = [f"{getattr(stats, f):.3f}" for f in fields]
        table.row(
            name, f"{rate:.0f}", *values, str(stats.frames_dropped), str(stats.watchdog_trips)
        )

    goals = []
    for rate in rates:
        result = run_glove_bench(
            channel=f"bench-{next(_channels)}",
            rate_hz=rate,
            seconds=args.seconds,
            repeats=args.repeats,
            priority=args.priority,
        )
        assert result.plain is not None and result.p99_ratio is not None
        row("plain python-can loop", rate, result.plain)
        row("host loop", rate, result.stats)
        with realtime_priority(args.priority):
            worlds = [world_loop(rate, args.seconds) for _ in range(args.repeats)]
        world = {f: float(np.median([getattr(w, f) for w in worlds])) for f in fields}
        table.row("world only", f"{rate:.0f}", *(f"{world[f]:.3f}" for f in fields), "", "")
        host, plain = result.stats.overrun_fraction, result.plain.overrun_fraction
        ok = result.p99_ratio <= GOAL_P99_RATIO and host <= GOAL_OVERRUN_RATIO * plain
        measured = (
            f"p99 ratio {result.p99_ratio:.2f}; overrun fraction host {host:.3f}, plain {plain:.3f}"
        )
        goals.append((rate, ok, measured))
    print()
    for rate, ok, measured in goals:
        report.check(
            f"at {rate:.0f} Hz, host / plain: p99 period <= {GOAL_P99_RATIO}, overrun fraction "
            f"<= {GOAL_OVERRUN_RATIO}",
            ok,
            measured,
        )
    with realtime_priority(args.priority):
        delays = watchdog_delays(args.silences)
    table = report.table(
        "The host watchdog: time from the last valid sample to the trip, the emulator going "
        f"quiet for 100 ms at 1 kHz, {args.silences} times (the watchdog's limit: 20 ms)",
        ["silences", "median [ms]", "max [ms]"],
    )
    table.row(str(args.silences), f"{np.median(delays):.2f}", f"{delays.max():.2f}")
    table = report.table(
        "The protocol's bus load: classic CAN at 1 Mbit/s, CAN FD at 1/5 Mbit/s",
        [
            "rate [Hz]",
            "classic, no stuff bits [%]",
            "classic, worst case [%]",
            "CAN FD, worst case [%]",
        ],
    )
    for rate in rates:
        classic, fd = bus_load(rate)["total"], bus_load(rate, fd=True)["total"]
        nominal = bus_load(rate, worst_case=False)["total"]
        table.row(f"{rate:.0f}", f"{100 * nominal:.1f}", f"{100 * classic:.1f}", f"{100 * fd:.1f}")


if __name__ == "__main__":
    raise SystemExit(main())

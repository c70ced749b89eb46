"""The glove's host loop on python-can's virtual bus at 500 Hz and 1 kHz, and the bus load.

Run: ``python bench/bench_glove_loop.py [--seconds 10] [--repeats 3] [--priority 10]``.
Against the in-process :class:`~ias_gym.hardware.GloveEmulator`, side by side in this one
run (:func:`~ias_gym.hardware.bench.run_glove_bench`, the runs alternating):

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

Prints per loop and rate the medians over ``--repeats`` runs of: period median / p99 / max
[ms], overrun fraction (periods > 1.5 x nominal), frames dropped, watchdog trips; the ratio
host / plain of the p99 period (the median of the runs' pairs) and the goal at 1 kHz
(p99 ratio <= 1.15, overruns <= 1.5 x the plain loop's);
the watchdog's trip delay (median, max); and the protocol's bus load at both rates (classic
CAN 1 Mbit/s; CAN FD 1/5 Mbit/s).
"""

from __future__ import annotations

import argparse
import itertools
import os
import platform
import subprocess
import sys
import time

import can
import numpy as np

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

    def write_feedback(self, torques: object) -> None:
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
    action = np.zeros(env.action_space.shape, dtype=np.float32)  # type: ignore[arg-type]
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
    args = parser.parse_args()
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, load average "
          f"{os.getloadavg()[0]:.1f}, {platform.python_implementation()} "
          f"{platform.python_version()}, python-can {can.__version__}; priority "
          f"{args.priority or 'default'}, {args.load} busy processes")  # fmt: skip
    load = busy_load(args.load)
    try:
        run(args)
    finally:
        for process in load:
            process.kill()
            process.wait()
    return 0


def run(args: argparse.Namespace) -> None:
    """The table, the watchdog delays and the bus load."""
    fields = ("period_median_ms", "period_p99_ms", "period_max_ms", "overrun_fraction")
    header = f"{'loop':<7} {'rate':>6} " + " ".join(f"{f:>17}" for f in fields)
    print(header + f" {'dropped':>8} {'trips':>6}")
    rates = [float(r) for r in args.rates.split(",")]

    def row(name: str, rate: float, stats: LoopStats) -> None:
        values = " ".join(f"{getattr(stats, f):>17.3f}" for f in fields)
        print(f"{name:<7} {rate:>6.0f} {values} {stats.frames_dropped:>8} "
              f"{stats.watchdog_trips:>6}", flush=True)  # fmt: skip

    for rate in rates:
        result = run_glove_bench(
            channel=f"bench-{next(_channels)}",
            rate_hz=rate,
            seconds=args.seconds,
            repeats=args.repeats,
            priority=args.priority,
        )
        assert result.plain is not None and result.p99_ratio is not None
        row("plain", rate, result.plain)
        row("host", rate, result.stats)
        with realtime_priority(args.priority):
            worlds = [world_loop(rate, args.seconds) for _ in range(args.repeats)]
        world = {f: float(np.median([getattr(w, f) for w in worlds])) for f in fields}
        print(f"{'world':<7} {rate:>6.0f} " + " ".join(f"{world[f]:>17.3f}" for f in fields))
        overruns = result.stats.overrun_fraction / max(result.plain.overrun_fraction, 1e-9)
        ok = result.p99_ratio <= GOAL_P99_RATIO and (
            result.stats.overrun_fraction <= GOAL_OVERRUN_RATIO * result.plain.overrun_fraction
        )
        print(f"        p99 ratio host / plain {result.p99_ratio:.2f}, overruns host / plain "
              f"{overruns:.2f}: goal (<= {GOAL_P99_RATIO}, <= {GOAL_OVERRUN_RATIO}) "
              f"{'met' if ok else 'NOT met'}", flush=True)  # fmt: skip
    with realtime_priority(args.priority):
        delays = watchdog_delays(args.silences)
    print(f"watchdog trip after the last valid sample ({args.silences} silences at 1 kHz, "
          f"limit 20 ms): median {np.median(delays):.2f} ms, "
          f"max {delays.max():.2f} ms")  # fmt: skip
    for rate in rates:
        classic, fd = bus_load(rate)["total"], bus_load(rate, fd=True)["total"]
        nominal = bus_load(rate, worst_case=False)["total"]
        print(f"bus load at {rate:.0f} Hz: classic {nominal:.1%} (no stuff bits) to "
              f"{classic:.1%} (worst case), CAN FD {fd:.1%} (worst case)")  # fmt: skip


if __name__ == "__main__":
    raise SystemExit(main())

"""``ias-gym glove-emulator`` and ``ias-gym glove-bench`` (thin: parse, call, print).

Numbers are checked when the arguments are parsed (argparse prints the usage and one line,
exit 2); what only running can tell (an interface this machine cannot open, a silent glove)
is raised as the package's own errors, which ``ias-gym`` prints as one line. The hardware
modules (python-can, the glove env) are imported when a command runs, so ``--help`` stays fast.
"""

from __future__ import annotations

import argparse
import json
import math
import signal
import subprocess
import sys
import threading
from collections.abc import Callable
from typing import Any

from ias_gym.errors import InputError
from ias_gym.glove.hand import PersonParams


def positive(kind: Callable[[str], float]) -> Callable[[str], Any]:
    """An argparse ``type``: ``kind(text)`` (``int`` or ``float``), finite and > 0."""

    def parse(text: str) -> float:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{text!r} is not a number ({kind.__name__})"
            ) from None
        if not 0 < value < math.inf:
            raise argparse.ArgumentTypeError(f"must be a positive number, got {text}")
        return value

    parse.__name__ = f"positive {kind.__name__}"
    return parse


def loop_rate(text: str) -> float:
    """An argparse ``type``: a loop rate [Hz] whose period is a whole number of the world's
    1 ms steps (1000, 500, 250, ... Hz)."""
    from ias_gym.hardware.loop import check_bench_numbers

    rate = positive(float)(text)
    try:
        check_bench_numbers(rate, 1.0)
    except InputError as e:
        raise argparse.ArgumentTypeError(str(e).removeprefix("--rate ")) from None
    return rate


def _bus_arguments(p: argparse.ArgumentParser, channel: str) -> None:
    p.add_argument(
        "--interface",
        default="virtual",
        metavar="NAME",
        help="python-can interface: virtual, socketcan, pcan, kvaser, udp_multicast, ... "
        "(default: %(default)s)",
    )
    p.add_argument(
        "--channel",
        default=channel,
        metavar="CH",
        help="the interface's channel (default: %(default)s)",
    )
    p.add_argument("--fd", action="store_true", help="CAN FD sensor frames (default: classic)")
    p.add_argument(
        "--bitrate",
        type=positive(int),
        metavar="BPS",
        help="passed to can.Bus (default: the protocol's 1000000)",
    )


def _bus_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    return {} if args.bitrate is None else {"bitrate": args.bitrate}


STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def _emulator(args: argparse.Namespace) -> int:
    stop = threading.Event()
    previous = {sig: signal.signal(sig, lambda *_: stop.set()) for sig in STOP_SIGNALS}
    try:
        return _run_emulator(args, stop)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _run_emulator(args: argparse.Namespace, stop: threading.Event) -> int:
    from ias_gym.hardware.can_glove import check_interface
    from ias_gym.hardware.emulator import GloveEmulator

    check_interface(args.interface)
    emulator = GloveEmulator(
        args.interface,
        args.channel,
        person=PersonParams.sample(args.person),
        seed=args.seed,
        rate_hz=args.rate,
        fd=args.fd,
        **_bus_kwargs(args),
    )
    with emulator:
        print(
            f"glove emulator: person {args.person}, {args.rate:g} Hz on "
            f"{args.interface}:{args.channel} ({'CAN FD' if args.fd else 'classic CAN'}); "
            "Ctrl-C stops",
            flush=True,
        )
        stop.wait(args.seconds)
    s = emulator.stats
    print(
        f"sent {s.samples} samples ({s.frames_sent} frames); commands: {s.commands} applied, "
        f"{s.commands_rejected} rejected, {s.commands_lost} lost, {s.safety_commands} safety; "
        f"watchdog trips {s.watchdog_trips}; late cycles {s.late_cycles}",
        flush=True,
    )
    return 0


def _emulator_process(args: argparse.Namespace) -> subprocess.Popen[str]:
    cmd = [
        sys.executable,
        "-m",
        "ias_gym.cli",
        "glove-emulator",
        "--interface",
        args.interface,
        "--channel",
        str(args.channel),
        "--rate",
        str(args.rate),
    ]
    if args.fd:
        cmd.append("--fd")
    if args.bitrate is not None:
        cmd += ["--bitrate", str(args.bitrate)]
    process = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    assert process.stdout is not None
    if not process.stdout.readline():  # its banner: the bus is open and samples are going out
        process.wait()
        raise InputError(
            f"the glove emulator process on {args.interface}:{args.channel} exited "
            f"(code {process.returncode}) before it sent a sample; its error is above"
        )
    return process


def _bench(args: argparse.Namespace) -> int:
    from ias_gym.hardware.bench import run_glove_bench
    from ias_gym.hardware.can_glove import check_interface
    from ias_gym.hardware.protocol import bus_load

    check_interface(args.interface)
    if args.emulator is None:
        args.emulator = "thread" if args.interface == "virtual" else "none"
    if args.emulator == "thread" and args.interface != "virtual":
        print("note: an in-process emulator on a real bus shares it with the glove", flush=True)
    if args.emulator == "process" and args.interface == "virtual":
        raise InputError(
            "--emulator process: python-can's virtual bus does not leave the process; use "
            "--emulator thread, or an interface such as udp_multicast"
        )
    process = _emulator_process(args) if args.emulator == "process" else None
    try:
        result = run_glove_bench(
            args.interface,
            args.channel,
            rate_hz=args.rate,
            seconds=args.seconds,
            fd=args.fd,
            emulate=args.emulator == "thread",
            bus_kwargs=_bus_kwargs(args),
            plain=not args.no_plain,
            repeats=args.repeats,
            priority=args.priority,
        )
    finally:
        if process is not None:
            process.send_signal(signal.SIGINT)
            try:
                process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                process.kill()
    out = result.as_dict()
    out["bus_load_worst_case"] = bus_load(args.rate, fd=args.fd)["total"]
    width = max(len(k) for k in out)
    print(
        f"glove bench: {args.rate:g} Hz for {args.seconds:g} s x {args.repeats} on "
        f"{args.interface} (emulator: {args.emulator})"
    )
    for key, value in out.items():
        text = f"{value:.4g}" if isinstance(value, float) else str(value)
        print(f"  {key:<{width}}  {text}")
    if args.json:
        print(json.dumps(out))
    return 0


def add_hardware_commands(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> None:
    """Add ``glove-emulator`` and ``glove-bench`` to the ``ias-gym`` sub-commands."""
    emu = subparsers.add_parser(
        "glove-emulator",
        help="speak the glove's CAN protocol with a simulated person behind it",
        description="Run the device side of the glove protocol (ias_gym.hardware.DBC_PATH) on "
        "a python-can bus: sensor frames at --rate, force-display torques applied, the "
        "device watchdog (no command for 20 ms -> torque off). Runs until Ctrl-C or --seconds.",
    )
    _bus_arguments(emu, "ias-glove")
    emu.add_argument(
        "--rate",
        type=positive(float),
        default=1000.0,
        metavar="HZ",
        help="sample rate [Hz] (default: %(default)g)",
    )
    emu.add_argument(
        "--person", default="p1", metavar="ID", help="simulated wearer (default: %(default)s)"
    )
    emu.add_argument(
        "--seed", type=int, default=0, metavar="S", help="sensor noise seed (default: %(default)s)"
    )
    emu.add_argument(
        "--seconds",
        type=positive(float),
        metavar="S",
        help="stop after S seconds (default: run until Ctrl-C)",
    )
    emu.set_defaults(run=_emulator)

    bench = subparsers.add_parser(
        "glove-bench",
        help="measure the host loop against the glove (or its emulator)",
        description="Run the host loop (read sensors -> calibrate -> step the virtual world -> "
        "send force display) of IAS-GloveHardware-v0 at --rate for --seconds and print its "
        "period statistics, dropped frames and watchdog trips, beside a plain python-can loop "
        "(drain, send one command) run the same way in the same invocation: plain_p99_ms, "
        "plain_overrun_fraction and p99_ratio (host p99 / plain p99).",
    )
    _bus_arguments(bench, "ias-glove-bench")
    bench.add_argument(
        "--rate",
        type=loop_rate,
        default=1000.0,
        metavar="HZ",
        help="loop rate [Hz]; the period must be a whole number of 1 ms (default: %(default)g)",
    )
    bench.add_argument(
        "--seconds",
        type=positive(float),
        default=5.0,
        metavar="S",
        help="how long each run lasts [s] (default: %(default)g)",
    )
    bench.add_argument(
        "--repeats",
        type=positive(int),
        default=1,
        metavar="N",
        help="runs per loop, alternating plain and host; the figures are medians "
        "(default: %(default)s)",
    )
    bench.add_argument(
        "--no-plain", action="store_true", help="skip the plain python-can loop (default: run it)"
    )
    bench.add_argument(
        "--priority",
        type=positive(int),
        metavar="P",
        help="run both loops and their threads under SCHED_FIFO at priority P (1-99; Linux, "
        "needs root or CAP_SYS_NICE) (default: the ordinary scheduler)",
    )
    bench.add_argument(
        "--emulator",
        choices=("thread", "process", "none"),
        default=None,
        help="where the glove emulator runs: a thread of this process (default on the "
        "virtual bus), a second process (needs a bus that crosses processes), or none "
        "(a real glove; the default on other interfaces)",
    )
    bench.add_argument("--json", action="store_true", help="print one JSON object last")
    bench.set_defaults(run=_bench)

"""``ias-gym glove-bench`` and ``ias-gym glove-emulator``: the host loop measured beside a plain
python-can loop, and one-line errors for what a user can get wrong (python-can's virtual bus)."""

from __future__ import annotations

import argparse
import json
import os

import pytest

from ias_gym.cli import build_parser, main
from ias_gym.errors import IasGymError, InputError
from ias_gym.hardware.bench import run_glove_bench
from ias_gym.hardware.loop import realtime_priority

pytestmark = [
    pytest.mark.realtime,
    pytest.mark.filterwarnings("error"),
    pytest.mark.usefixtures("no_gc_pauses"),
]


def run_command(argv: list[str]) -> int:
    """The command function itself (what ``ias-gym`` calls after parsing): its exceptions
    reach the test whatever ``main`` does with them."""
    args = build_parser().parse_args(argv)
    code: int = args.run(args)
    return code


def test_glove_bench_prints_its_statistics_as_json(
    channel: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(
        ["glove-bench", "--rate", "500", "--seconds", "0.4", "--channel", channel, "--json"]
    )
    assert code == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    keys = {"rate_hz", "period_median_ms", "period_p99_ms", "period_max_ms"}
    keys |= {"overrun_fraction", "frames_dropped", "watchdog_trips"}
    assert keys <= set(result)
    # every cycle is measured, also after a watchdog trip (the bench re-arms the glove); how
    # often the 20 ms watchdog trips is the machine's timing, measured, not asserted here
    assert result["cycles"] == 199
    assert isinstance(result["watchdog_trips"], int) and 0 <= result["watchdog_trips"] <= 199
    assert 0 < result["period_median_ms"] <= result["period_p99_ms"] <= result["period_max_ms"]


def test_glove_bench_reports_the_plain_loop_beside_the_host_loop(
    channel: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """The p99 is only comparable with a plain python-can loop measured in the same run: the
    JSON carries it and the ratio, the median of the runs' host / plain pairs."""
    code = main(
        ["glove-bench", "--rate", "500", "--seconds", "0.3", "--repeats", "2",
         "--channel", channel, "--json"]
    )  # fmt: skip
    assert code == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert result["cycles"] == 2 * 149 and result["runs"] == 2  # both runs of the host loop
    assert 0 < result["plain_period_median_ms"] <= result["plain_p99_ms"]
    assert 0 <= result["plain_overrun_fraction"] <= 1
    assert result["p99_ratio"] > 0
    # one run: the ratio is exactly host p99 / plain p99 of that run
    one = run_glove_bench(channel=channel, rate_hz=500.0, seconds=0.3)
    assert one.plain is not None
    assert one.p99_ratio == one.stats.period_p99_ms / one.plain.period_p99_ms


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["glove-bench", "--rate", "0"], "--rate: must be a positive number"),
        (["glove-bench", "--rate", "-1000"], "--rate: must be a positive number"),
        (["glove-bench", "--rate", "300"], "--rate: 300 Hz: the period must be a whole number"),
        (["glove-bench", "--rate", "fast"], "--rate: 'fast' is not a number"),
        (["glove-bench", "--seconds", "-1"], "--seconds: must be a positive number"),
        (["glove-bench", "--seconds", "inf"], "--seconds: must be a positive number"),
        (["glove-bench", "--repeats", "0"], "--repeats: must be a positive number"),
        (["glove-bench", "--bitrate", "0"], "--bitrate: must be a positive number"),
        (["glove-emulator", "--rate", "0"], "--rate: must be a positive number"),
        (["glove-emulator", "--seconds", "-1"], "--seconds: must be a positive number"),
        (["glove-emulator", "--rate", "nan"], "--rate: must be a positive number"),
    ],
)
def test_numbers_out_of_range_are_refused_when_parsed(
    argv: list[str], match: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """No ZeroDivisionError 15 frames deep, no emulator running for -1 s: argparse's usage
    and one line naming the option, exit code 2, before anything runs."""
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert match in err and "Traceback" not in err


def test_help_shows_the_defaults(capsys: pytest.CaptureFixture[str]) -> None:
    for command in ("glove-bench", "glove-emulator"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        out = " ".join(capsys.readouterr().out.split())
        assert "(default: 1000)" in out  # --rate
        assert "(default: virtual)" in out  # --interface
    with pytest.raises(SystemExit):
        main(["glove-bench", "--help"])
    assert "(default: 5)" in " ".join(capsys.readouterr().out.split())  # --seconds


@pytest.mark.parametrize("command", ["glove-bench", "glove-emulator"])
def test_an_unknown_interface_is_one_input_error(command: str) -> None:
    with pytest.raises(InputError, match=r"unknown CAN interface 'bogus'.*virtual"):
        run_command([command, "--interface", "bogus", "--seconds", "0.1"])


@pytest.mark.parametrize("command", ["glove-bench", "glove-emulator"])
def test_a_bus_this_machine_cannot_open_is_one_input_error(command: str) -> None:
    """socketcan on a machine without SocketCAN (OSError: address family not supported) or
    without that interface (No such device): one error naming interface and channel."""
    with pytest.raises(InputError, match="cannot open CAN interface 'socketcan' channel 'ias-no"):
        run_command(
            [command, "--interface", "socketcan", "--channel", "ias-no-such-can", "--seconds",
             "0.1"]
        )  # fmt: skip


def test_the_hardware_env_says_when_its_bus_cannot_be_opened() -> None:
    """``ias-gym evaluate --env IAS-GloveHardware-v0 --env-kwargs '{"interface": ...}'``."""
    from ias_gym.evaluation import evaluate_spec

    with pytest.raises(InputError, match="unknown CAN interface 'bogus'"):
        evaluate_spec("IAS-GloveHardware-v0", "teleop", 1, env_kwargs={"interface": "bogus"})
    with pytest.raises(InputError, match="cannot open CAN interface 'socketcan'"):
        evaluate_spec(
            "IAS-GloveHardware-v0",
            "teleop",
            1,
            env_kwargs={"interface": "socketcan", "channel": "ias-no-such-can"},
        )


def test_a_silent_glove_is_a_package_error_not_a_return_code(channel: str) -> None:
    """No glove on the bus: GloveTimeoutError (an IasGymError) reaches ``main``, which prints
    it as one line; the command does not print and return 1 on its own."""
    with pytest.raises(IasGymError, match="glove-emulator"):
        run_command(["glove-bench", "--emulator", "none", "--channel", channel,
                     "--seconds", "0.1"])  # fmt: skip


def test_glove_bench_refuses_a_process_emulator_on_the_virtual_bus() -> None:
    with pytest.raises(InputError, match="does not leave the process"):
        run_command(["glove-bench", "--emulator", "process", "--seconds", "0.1"])


def test_glove_emulator_command_runs_and_reports(
    channel: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["glove-emulator", "--channel", channel, "--rate", "500", "--seconds", "0.2"])
    out = capsys.readouterr().out
    assert code == 0 and "Ctrl-C stops" in out
    sent = int(out.split("sent ")[1].split(" samples")[0])
    assert 50 <= sent <= 110  # 500 Hz for 0.2 s


def test_realtime_priority_is_checked_applied_and_undone() -> None:
    for bad in (0, 100):
        with pytest.raises(InputError, match="--priority must be 1 to 99"), realtime_priority(bad):
            pass
    before = os.sched_getscheduler(0)
    try:
        with realtime_priority(5):
            assert os.sched_getscheduler(0) == os.SCHED_FIFO
            assert os.sched_getparam(0).sched_priority == 5
    except InputError as e:  # not root and no CAP_SYS_NICE: the error says what grants it
        assert "CAP_SYS_NICE" in str(e)
    assert os.sched_getscheduler(0) == before


def test_priority_type_is_checked_when_parsed() -> None:
    with pytest.raises(SystemExit):
        build_parser().parse_args(["glove-bench", "--priority", "0"])
    args = build_parser().parse_args(["glove-bench", "--priority", "7"])
    assert isinstance(args, argparse.Namespace) and args.priority == 7

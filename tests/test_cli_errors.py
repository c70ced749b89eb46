"""``ias-gym``: a user's mistake is one line on stderr and exit code 2, never a traceback.

Argument values out of range are argparse usage errors (exit code 2 as well); ``--debug``
shows the traceback instead; a bug (an error that is not the package's) still raises.
"""

from __future__ import annotations

import json
from collections.abc import Sequence

import gymnasium as gym
import pytest

import ias_gym.evaluation
from ias_gym.cli import is_user_error, main
from ias_gym.errors import InputError
from ias_gym.evaluation import UnknownEnvError, make_env


def _one_error_line(argv: Sequence[str], capsys: pytest.CaptureFixture[str]) -> str:
    """Run ``main(argv)``; assert exit code 2 and exactly one stderr line; return it."""
    assert main(list(argv)) == 2
    captured = capsys.readouterr()
    lines = [line for line in captured.err.splitlines() if line.strip()]
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("ias-gym: error: ")
    assert "Traceback" not in captured.err
    return lines[0]


EVALUATE = ["evaluate", "--env", "IAS-PenSlide-v0", "--episodes", "1"]


def test_unknown_env_id_names_it_and_lists_the_ias_envs(
    capsys: pytest.CaptureFixture[str],
) -> None:
    line = _one_error_line(["evaluate", "--env", "IAS-PenSlid-v0"], capsys)
    assert "'IAS-PenSlid-v0'" in line and "Did you mean: `IAS-PenSlide`" in line
    for env_id in ("IAS-PenSlide-v0", "IAS-PenRotate-v0", "IAS-GloveGrasp-v0"):
        assert env_id in line
    line = _one_error_line(["evaluate", "--env", "NoNamespace/Nothing-v3"], capsys)
    assert "NoNamespace" in line


@pytest.mark.parametrize(
    ("kwargs", "expected"),
    [
        ({"not_a_setting": 1}, ["not_a_setting", "known:", "duration"]),  # unknown, listed
        ({"duration": "long"}, ["'duration': 'long'"]),  # ill-typed
        ({"duration": -1.0}, ["'duration': -1.0"]),  # out of range
    ],
)
def test_bad_env_kwargs_name_the_kwarg(
    kwargs: dict[str, object], expected: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    line = _one_error_line([*EVALUATE, "--env-kwargs", json.dumps(kwargs)], capsys)
    assert "IAS-PenSlide-v0 does not accept env kwargs" in line
    for text in expected:
        assert text in line
    assert "was raised from the environment creator" not in line  # said once, not twice


def test_make_env_converts_gymnasium_and_constructor_errors() -> None:
    with pytest.raises(UnknownEnvError, match="IAS-PenRotate-v0"):
        make_env("IAS-Nothing-v0")
    with pytest.raises(InputError, match="unknown config"):
        make_env("IAS-PenRotate-v0", amplitud=0.1)
    with pytest.raises(InputError, match=r"amplitude=1.0 rad is outside"):
        make_env("IAS-PenRotate-v0", amplitude=1.0)


@pytest.mark.parametrize(
    ("extra", "expected"),
    [
        (["--env-kwargs", "{duration: 1}"], "--env-kwargs is not JSON"),
        (["--env-kwargs", "[1, 2]"], "--env-kwargs must be a JSON object"),
        (["--policy", "no/such/model.zip"], "not 'expert', 'teleop', 'random'"),
        (["--policy", "teleop"], "needs a glove env"),
    ],
)
def test_input_errors_of_evaluate_are_one_line(
    extra: list[str], expected: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert expected in _one_error_line([*EVALUATE, *extra], capsys)


def test_glove_env_has_no_expert(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["evaluate", "--env", "IAS-GloveGrasp-v0", "--episodes", "1"]
    assert "has no expert" in _one_error_line(argv, capsys)


def test_debug_shows_the_traceback(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(InputError, match="--env-kwargs is not JSON"):
        main(["--debug", *EVALUATE, "--env-kwargs", "{"])
    assert "ias-gym: error" not in capsys.readouterr().err


def test_gymnasium_errors_are_one_line_and_bugs_still_raise(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def gym_error(*args: object, **kwargs: object) -> None:
        raise gym.error.ResetNeeded("Cannot call env.step() before calling env.reset()\nat all")

    monkeypatch.setattr(ias_gym.evaluation, "run_episode", gym_error)
    line = _one_error_line(EVALUATE, capsys)
    assert line == "ias-gym: error: Cannot call env.step() before calling env.reset() at all"

    def bug(*args: object, **kwargs: object) -> None:
        raise ZeroDivisionError("a bug, not the user's mistake")

    monkeypatch.setattr(ias_gym.evaluation, "run_episode", bug)
    with pytest.raises(ZeroDivisionError):
        main(EVALUATE)
    assert is_user_error(InputError("x")) and not is_user_error(KeyError("x"))


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        ([*EVALUATE[:3], "--episodes", "0"], "argument --episodes: must be >= 1, got 0"),
        ([*EVALUATE[:3], "--episodes", "two"], "expected an integer >= 1, got 'two'"),
        ([*EVALUATE, "--seed", "-1"], "argument --seed: must be >= 0, got -1"),
        (["figure", "control-error", "--out", "x", "--initial-error", "0.9"], "outside [0, 0.5]"),
        (["figure", "control-error", "--out", "x", "--initial-error", "nan"], "outside [0, 0.5]"),
        (["figure", "control-error", "--out", "x", "--initial-error", "-0.1"], "outside"),
    ],
)
def test_out_of_range_numbers_are_usage_errors(
    argv: list[str], expected: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["evaluate", "--help"], ["(default: 10)", "(default: 0)", "(default: expert)"]),
        (["figure", "control-error", "--help"], ["(default: 0.1)"]),
        (["figure", "wrench-intensities", "--help"], ["(default: box)"]),
    ],
)
def test_help_shows_the_defaults(
    argv: list[str], expected: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 0
    out = " ".join(capsys.readouterr().out.split())  # argparse wraps lines
    for text in expected:
        assert text in out
    assert "(default: None)" not in out  # required options have none to show

"""Argument helpers shared by the ``ias-gym`` command groups (argparse types and options).

Only argparse, json and the package's errors: every command module of :mod:`ias_gym.cli`
imports this one, and it imports no command module (no circle through ``cli/__init__``).
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from typing import Any

from ias_gym.errors import InputError


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """``--help`` with each option's default, except where there is none to show (required
    options, ``None`` defaults, flags)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.required or action.default is None or action.nargs == 0:
            return action.help
        return super()._get_help_string(action)


def int_at_least(minimum: int) -> Callable[[str], int]:
    """argparse type: an integer >= ``minimum`` (``int_at_least(1)`` for counts, 0 for seeds).

    The returned function raises ``argparse.ArgumentTypeError`` otherwise (argparse reports
    it, exit code 2).
    """

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected an integer >= {minimum}, got {text!r}"
            ) from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be >= {minimum}, got {value}")
        return value

    return parse


#: argparse types of counts (>= 1) and seeds (>= 0).
positive_int = int_at_least(1)
non_negative_int = int_at_least(0)


def parse_env_kwargs(text: str) -> dict[str, Any]:
    """The value of ``--env-kwargs``: a JSON object.

    Raises:
        InputError: not JSON, or not an object (the message says which).
    """
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"--env-kwargs is not JSON ({exc}): {text!r}") from None
    if not isinstance(value, dict):
        raise InputError(f"--env-kwargs must be a JSON object, got {text!r}")
    return value


def env_kwargs_argument(parser: argparse.ArgumentParser) -> None:
    """Add ``--env-kwargs JSON`` (configuration overrides passed to ``gym.make``)."""
    parser.add_argument(
        "--env-kwargs",
        default="{}",
        metavar="JSON",
        help="env configuration overrides, e.g. '{\"duration\": 0.5}'",
    )


def overwrite_argument(parser: argparse.ArgumentParser) -> None:
    """Add ``--overwrite`` (replace existing output files; without it they are refused)."""
    parser.add_argument(
        "--overwrite", action="store_true", help="replace existing output files (else refused)"
    )

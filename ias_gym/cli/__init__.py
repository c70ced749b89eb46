"""The ``ias-gym`` command: one module per command group, its argument parsing beside it.

- :mod:`~ias_gym.cli.args`: argparse types and options shared by the groups;
- :mod:`~ias_gym.cli.figure_commands`: ``figure wrench-intensities|control-error``;
- :mod:`~ias_gym.cli.evaluate_command`: ``evaluate``;
  :mod:`~ias_gym.cli.robustness_command`: ``robustness``;
- :mod:`~ias_gym.cli.skills_commands`:
  ``skills record|list|show|export|check|delete|migrate|merge``;
  :mod:`~ias_gym.cli.transfer_command`: ``skills transfer``;
- :mod:`~ias_gym.cli.glove_commands`: ``calibrate``;
- :mod:`~ias_gym.cli.hardware_commands`: ``glove-emulator``, ``glove-bench``.

This is the top layer: it imports the library, the library never imports it. Every command
imports what it needs when it runs, so ``ias-gym --help`` stays fast.

Errors: a command raises :class:`~ias_gym.errors.IasGymError` (usually
:class:`~ias_gym.errors.InputError`) for anything the user can fix; :func:`main` prints it
as one line, ``ias-gym: error: ...``, on stderr and returns 2 (``--debug``: the traceback
instead). Numbers are range-checked when the arguments are parsed (argparse's usage error,
also exit code 2).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

from ias_gym.cli.args import (
    HelpFormatter,
    env_kwargs_argument,
    int_at_least,
    non_negative_int,
    parse_env_kwargs,
    positive_int,
)
from ias_gym.cli.assist_commands import add_assist_commands
from ias_gym.cli.evaluate_command import add_evaluate_command
from ias_gym.cli.figure_commands import add_figure_commands
from ias_gym.cli.glove_commands import add_glove_commands
from ias_gym.cli.hardware_commands import add_hardware_commands
from ias_gym.cli.robustness_command import add_robustness_command
from ias_gym.cli.skills_commands import add_skills_commands
from ias_gym.errors import IasGymError

#: Exit code of a usage or input error (argparse's own too).
EXIT_USAGE = 2


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``ias-gym`` with one sub-parser per command."""
    parser = argparse.ArgumentParser(
        prog="ias-gym",
        description="Dextrous in-hand manipulation after the IAS sensor-hand paper.",
        formatter_class=HelpFormatter,
    )
    parser.add_argument(
        "--debug",
        action="store_true",
        help="show the traceback of an error instead of its one-line message",
    )
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    add_figure_commands(commands)
    add_evaluate_command(commands)
    add_robustness_command(commands)
    add_skills_commands(commands)
    add_glove_commands(commands)
    add_hardware_commands(commands)
    add_assist_commands(commands)
    return parser


def is_user_error(exc: BaseException) -> bool:
    """Whether ``exc`` is reported as one line rather than a traceback: the package's own
    errors and gymnasium's (an unknown env id, ...)."""
    if isinstance(exc, IasGymError):
        return True
    gym = sys.modules.get("gymnasium")  # never imported just to ask
    return gym is not None and isinstance(exc, gym.error.Error)


def one_line(exc: BaseException) -> str:
    """The message of ``exc`` on one line (its type name if it has none)."""
    return " ".join(str(exc).split()) or type(exc).__name__


def user_error(exc: BaseException, debug: bool, prefix: str = "ias-gym: error") -> int:
    """Report ``exc`` caught by a command: one line ``<prefix>: <message>`` on stderr and
    :data:`EXIT_USAGE` for an error the user can fix (:func:`is_user_error`); re-raised, with
    its traceback, for any other error or with ``debug``. Call it inside ``except``."""
    if debug or not is_user_error(exc):
        raise exc
    print(f"{prefix}: {one_line(exc)}", file=sys.stderr)
    return EXIT_USAGE


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``ias-gym`` console script.

    Args:
        argv: the arguments (default: ``sys.argv[1:]``).

    Returns:
        The exit code: 0, or :data:`EXIT_USAGE` (2) after printing one line
        ``ias-gym: error: <message>`` on stderr for an error the user can fix.

    Raises:
        SystemExit: from argparse (``--help``: 0, a usage error: 2).
    """
    args = build_parser().parse_args(argv)
    run: Callable[[argparse.Namespace], int] = args.run
    try:
        return run(args)
    except Exception as exc:
        return user_error(exc, args.debug)


__all__ = [
    "EXIT_USAGE",
    "HelpFormatter",
    "build_parser",
    "env_kwargs_argument",
    "int_at_least",
    "is_user_error",
    "main",
    "non_negative_int",
    "one_line",
    "parse_env_kwargs",
    "positive_int",
    "user_error",
]

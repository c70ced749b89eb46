"""Argument helpers shared by the ``ias-gym`` command groups (argparse types and options).

Only argparse, json and the package's errors: every command module of :mod:`ias_gym.cli`
imports this one, and it imports no command module (no circle through ``cli/__init__``).
:func:`backend_from_args` imports :mod:`ias_gym.runtime.jobs` when it runs (no gymnasium).
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ias_gym.errors import InputError

if TYPE_CHECKING:
    from ias_gym.runtime.jobs import Backend


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


def policy_arguments(
    parser: argparse.ArgumentParser,
    *,
    episodes: int,
    episodes_help: str = "number of episodes",
    policies: str = "expert|teleop|random|shipped|PATH",
    policy_help: str = "the grip-transform expert (pen tasks), zero action (glove envs: the "
    "glove alone drives the hand), uniform random actions, the model shipped for the env "
    "(ias_gym/assets/policies), or a saved SB3 model (.zip, loaded without running code "
    "from it)",
) -> None:
    """Add the policy and episode options of ``evaluate``, ``robustness`` and ``skills
    record``: ``--policy`` (default ``expert``), ``--trust-pickle``, ``--episodes N``
    (>= 1) and ``--seed S`` (>= 0, the first episode's; episode ``i`` has ``S + i``).

    Args:
        parser: the command's parser.
        episodes: the default of ``--episodes``.
        episodes_help: its help text.
        policies: the metavar of ``--policy`` (the specs the command accepts).
        policy_help: its help text.
    """
    parser.add_argument("--policy", default="expert", metavar=policies, help=policy_help)
    parser.add_argument(
        "--trust-pickle",
        action="store_true",
        help="load a model file with SB3's own load, which unpickles it and so runs code "
        "stored in it: only for files you trust",
    )
    episode_arguments(
        parser,
        episodes,
        episodes_help,
        seed_help="seed of the first episode (episode i has seed S + i, whichever worker runs it)",
    )


def episode_arguments(
    parser: argparse.ArgumentParser,
    episodes: int,
    episodes_help: str,
    seed: int = 0,
    seed_help: str = "reset seed of the first session",
) -> None:
    """Add ``--episodes N`` (>= 1, default ``episodes``) and ``--seed S`` (>= 0, default
    ``seed``): how many episodes or sessions a command runs, and the first one's seed."""
    parser.add_argument(
        "--episodes", type=positive_int, default=episodes, metavar="N", help=episodes_help
    )
    parser.add_argument("--seed", type=non_negative_int, default=seed, metavar="S", help=seed_help)


class _WorkersAction(argparse.Action):
    """``--workers N``; N > 1 together with ``--ray`` (in either order) is a usage error."""

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: Any,
        option_string: str | None = None,
    ) -> None:
        if values > 1 and getattr(namespace, "ray", None) is not None:
            raise argparse.ArgumentError(self, _EXCLUSIVE)
        setattr(namespace, self.dest, values)


class _RayAction(argparse.Action):
    """``--ray [ADDRESS]`` (``""``: a local Ray); with ``--workers N > 1`` a usage error."""

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: Any,
        option_string: str | None = None,
    ) -> None:
        if getattr(namespace, "workers", 1) > 1:
            raise argparse.ArgumentError(self, _EXCLUSIVE)
        setattr(namespace, self.dest, values)


_EXCLUSIVE = "--ray and --workers N > 1 exclude each other (Ray runs its own workers)"


def parallel_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--workers N`` (local worker processes, >= 1, default 1: this process) and
    ``--ray [ADDRESS]`` (a Ray cluster; without ADDRESS a local one is started).

    Using both (``--workers`` > 1) is a usage error (exit code 2). The options make a
    :class:`~ias_gym.runtime.jobs.Backend` with :func:`backend_from_args`.
    """
    parser.add_argument(
        "--workers",
        type=positive_int,
        default=1,
        action=_WorkersAction,
        metavar="N",
        help="run the episodes on N local worker processes (1: in this process); results "
        "are the same for every N",
    )
    parser.add_argument(
        "--ray",
        nargs="?",
        const="",
        default=None,
        action=_RayAction,
        metavar="ADDRESS",
        help="run the episodes as Ray tasks on the cluster at ADDRESS (auto, HOST:PORT, "
        "ray://HOST:PORT), or without ADDRESS on a local Ray started for the run (needs the "
        "distributed extra)",
    )


def backend_from_args(args: argparse.Namespace) -> Backend:
    """The backend of ``--workers`` and ``--ray`` (:func:`parallel_arguments`).

    Raises:
        RayMissingError: ``--ray`` without Ray installed (one line: the extra to install).
    """
    from ias_gym.runtime.jobs import Backend

    return Backend.from_options(args.workers, args.ray)

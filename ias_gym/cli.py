"""The ``ias-gym`` command: parses arguments and calls the packages (nothing else lives here).

Every command imports what it needs when it runs, so ``ias-gym --help`` stays fast.

Errors: a command raises :class:`~ias_gym.errors.IasGymError` (usually
:class:`~ias_gym.errors.InputError`) for anything the user can fix; :func:`main` prints it
as one line, ``ias-gym: error: ...``, on stderr and returns 2 (``--debug``: the traceback
instead). Numbers are range-checked when the arguments are parsed (argparse's usage error,
also exit code 2).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from ias_gym.errors import IasGymError, InputError

#: Exit code of a usage or input error (argparse's own too).
EXIT_USAGE = 2


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


def _initial_error(text: str) -> float:
    """argparse type of ``--initial-error``: a finite angle in the figure's range [rad]."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number [rad], got {text!r}") from None
    from ias_gym.figures.control_error import check_initial_error

    try:
        return check_initial_error(value)
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


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


def _figure_wrench_intensities(args: argparse.Namespace) -> int:
    from ias_gym.figures.wrench_intensities import write_wrench_intensity_figure

    csv_path, png_path = write_wrench_intensity_figure(
        Path(args.out), cone=args.cone, overwrite=args.overwrite
    )
    print(f"wrote {csv_path}")
    print(f"wrote {png_path}")
    return 0


def _figure_control_error(args: argparse.Namespace) -> int:
    from ias_gym.figures.control_error import write_control_error_figure

    paths = write_control_error_figure(
        Path(args.out), initial_error=args.initial_error, overwrite=args.overwrite
    )
    for path in paths:
        print(f"wrote {path}")
    return 0


def _evaluate(args: argparse.Namespace) -> int:
    from ias_gym.evaluation import evaluate

    result = evaluate(
        args.env,
        policy=args.policy,
        episodes=args.episodes,
        seed=args.seed,
        video=None if args.video is None else Path(args.video),
        progress=not args.json,
        env_kwargs=parse_env_kwargs(args.env_kwargs),
        overwrite=args.overwrite,
        trust_pickle=args.trust_pickle,
    )
    summary = result.summary()
    if args.video is not None:
        summary["video"] = str(args.video)
    if args.json:
        print(json.dumps(summary))
    else:
        width = max(len(k) for k in summary)
        for key, value in summary.items():
            print(
                f"{key:<{width}}  {value:.6g}"
                if isinstance(value, float)
                else f"{key:<{width}}  {value}"
            )
    return 0


def _robustness(args: argparse.Namespace) -> int:
    from ias_gym.robustness import check_classes, run_robustness, summary_row

    classes = check_classes(None if args.classes is None else args.classes.split(","))
    rows = run_robustness(
        args.env,
        policy=args.policy,
        episodes=args.episodes,
        seed=args.seed,
        classes=classes,
        env_kwargs=parse_env_kwargs(args.env_kwargs),
        progress=not args.json,
        trust_pickle=args.trust_pickle,
    )
    last = summary_row(rows)
    if args.json:
        for row in rows:
            print(json.dumps(row.as_json()))
        print(json.dumps(last))
        return 0
    width = max(len(r.disturbance) for r in rows)
    print(f"{'disturbance':<{width}}  success  episodes")
    for row in rows:
        print(f"{row.disturbance:<{width}}  {row.success_rate:7.0%}  {row.episodes:8d}")
    print(f"{'all (minimum)':<{width}}  {last['success_rate']:7.0%}  {last['episodes']:8d}")
    return 0


def _overwrite_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--overwrite", action="store_true", help="replace existing output files (else refused)"
    )


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

    figure = commands.add_parser(
        "figure", help="reproduce a figure of the paper", formatter_class=HelpFormatter
    )
    figures = figure.add_subparsers(dest="figure", metavar="FIGURE", required=True)
    wrench = figures.add_parser(
        "wrench-intensities",
        help="Fig. 8: wrench intensities c(t) of the pen-sliding skill (CSV + PNG)",
        description="Solve the internal-force problem of eqs. (19)-(24) along the sliding "
        "schedule of eq. (17) and write DIR/wrench_intensities.csv and .png.",
        formatter_class=HelpFormatter,
    )
    wrench.add_argument(
        "--out", required=True, metavar="DIR", help="output directory (created if missing)"
    )
    _overwrite_argument(wrench)
    wrench.add_argument(
        "--cone",
        choices=("box", "exact"),
        default="box",
        help="friction cone: the paper's linearised box (LP) or the exact Coulomb cone (SOCP)",
    )
    wrench.set_defaults(run=_figure_wrench_intensities)
    control = figures.add_parser(
        "control-error",
        help="Fig. 9: the pen rotation under the control law from an initial error (CSV + PNG)",
        description="Run the grip-transform expert on IAS-PenRotate-v0 from a tilt error and "
        "write DIR/control_error.csv (t, e_roll, e_pitch, e_yaw, pos_err, "
        "internal_force_err) and .png.",
        formatter_class=HelpFormatter,
    )
    control.add_argument(
        "--out", required=True, metavar="DIR", help="output directory (created if missing)"
    )
    _overwrite_argument(control)
    control.add_argument(
        "--initial-error",
        type=_initial_error,
        default=0.1,
        metavar="RAD",
        help="magnitude of the tilt error at reset [rad], 0 to 0.5",
    )
    control.set_defaults(run=_figure_control_error)

    evaluate = commands.add_parser(
        "evaluate",
        help="run a policy on an environment: success rate, return, task errors",
        description="Evaluate a policy over N seeded episodes (seeds S, S+1, ...). Task "
        "errors are printed with their unit in the name (_mm, _deg, _pct, _N).",
        formatter_class=HelpFormatter,
    )
    evaluate.add_argument("--env", required=True, metavar="ID", help="e.g. IAS-PenSlide-v0")
    evaluate.add_argument(
        "--policy",
        default="expert",
        metavar="expert|teleop|random|PATH",
        help="the grip-transform expert (pen tasks), zero action (glove envs: the glove "
        "alone drives the hand), uniform random actions, or a saved SB3 model (.zip, "
        "loaded without running code from it)",
    )
    evaluate.add_argument(
        "--trust-pickle",
        action="store_true",
        help="load a model file with SB3's own load, which unpickles it and so runs code "
        "stored in it: only for files you trust",
    )
    evaluate.add_argument(
        "--episodes", type=positive_int, default=10, metavar="N", help="number of episodes"
    )
    evaluate.add_argument(
        "--seed", type=non_negative_int, default=0, metavar="S", help="seed of the first episode"
    )
    evaluate.add_argument(
        "--json", action="store_true", help="print one JSON object as the last line"
    )
    evaluate.add_argument(
        "--video",
        metavar="FILE",
        help="write an MP4 of the first episode (its directory must exist; checked first)",
    )
    _overwrite_argument(evaluate)
    env_kwargs_argument(evaluate)
    evaluate.set_defaults(run=_evaluate)

    robustness = commands.add_parser(
        "robustness",
        help="a policy's success rate under each class of disturbance (pen tasks)",
        description="Evaluate a policy on the same seeds under each disturbance class of "
        "ias_gym.robustness.DISTURBANCES (pen friction and mass scaled, a push, sensor noise, "
        "action noise and delay, internal-force reference steps). With --json: one object per "
        'class, then one with "disturbance": "all" and the minimum success rate.',
        formatter_class=HelpFormatter,
    )
    robustness.add_argument("--env", required=True, metavar="ID", help="e.g. IAS-PenRotate-v0")
    robustness.add_argument(
        "--policy",
        default="expert",
        metavar="expert|random|PATH",
        help="the grip-transform expert, uniform random actions, or a saved SB3 model (.zip)",
    )
    robustness.add_argument(
        "--trust-pickle", action="store_true", help="as for evaluate: only for files you trust"
    )
    robustness.add_argument(
        "--episodes", type=positive_int, default=100, metavar="N", help="episodes per class"
    )
    robustness.add_argument(
        "--seed", type=non_negative_int, default=0, metavar="S", help="seed of the first episode"
    )
    robustness.add_argument(
        "--classes",
        metavar="A,B,...",
        help="only these classes (default: all; names in ias_gym.robustness.DISTURBANCES)",
    )
    robustness.add_argument(
        "--json", action="store_true", help="one JSON object per line, the summary last"
    )
    env_kwargs_argument(robustness)
    robustness.set_defaults(run=_robustness)

    from ias_gym.skills.commands import add_skills_commands

    add_skills_commands(commands)

    from ias_gym.glove.commands import add_glove_commands

    add_glove_commands(commands)

    from ias_gym.hardware.commands import add_hardware_commands

    add_hardware_commands(commands)
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
        if args.debug or not is_user_error(exc):
            raise
        print(f"ias-gym: error: {one_line(exc)}", file=sys.stderr)
        return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())

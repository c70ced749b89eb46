"""``ias-gym figure wrench-intensities|control-error``: the paper's Figs. 8 and 9 (CSV + PNG).

The figure modules are imported when a command runs (they pull in MuJoCo and matplotlib),
so ``ias-gym --help`` stays fast.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ias_gym.cli.args import HelpFormatter, overwrite_argument
from ias_gym.errors import InputError


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


def add_figure_commands(subparsers: argparse._SubParsersAction[Any]) -> None:
    """Add ``figure`` with its sub-commands ``wrench-intensities`` and ``control-error``.

    Args:
        subparsers: the object ``parser.add_subparsers(...)`` returned; each leaf parser
            sets ``run`` (``args -> exit code``) as its default.
    """
    figure = subparsers.add_parser(
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
    overwrite_argument(wrench)
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
    overwrite_argument(control)
    control.add_argument(
        "--initial-error",
        type=_initial_error,
        default=0.1,
        metavar="RAD",
        help="magnitude of the tilt error at reset [rad], 0 to 0.5",
    )
    control.set_defaults(run=_figure_control_error)

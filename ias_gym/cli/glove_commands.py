"""The ``ias-gym calibrate`` command: calibrate a simulated person's glove (paper 2.4, Fig. 7).

:func:`add_glove_commands` adds ``calibrate`` to the ``ias-gym`` parser's sub-commands::

    ias-gym calibrate --person ID [--seed S] --out DIR [--json] [--overwrite [--force]]

It records a simulated calibration session for person ID (:class:`PersonParams` sampled from
the id), trains the calibration (:func:`~ias_gym.glove.training.calibrate_person`), writes
``DIR/profile_<ID>.json`` (the person's profile) and ``DIR/calibration_<ID>.png`` (Fig. 7 in
our terms: a held-out pinch pose, index finger and thumb as planar stick figures, the truth
against (a) the linear calibration and (b) the ANN), and prints the held-out errors. With
``--json`` the last line is one JSON object with ``ann_rms_deg``, ``linear_rms_deg`` (joint
RMS over all joints), ``ann_pinch_rms_deg``, ``linear_pinch_rms_deg`` (pinch poses),
``ann_pinch_gap_mm``, ``linear_pinch_gap_mm`` (fingertip gap error in pinch), and more.
Torch and matplotlib are imported when the command runs, so ``--help`` stays fast.

Nothing is overwritten silently: if the profile or the figure exists, the command refuses
unless ``--overwrite``; even then it keeps an existing profile whose held-out joint RMS
error is lower than the new one's (each measured on its own held-out readings) unless
``--force``. Ids follow :func:`~ias_gym.glove.ids.check_id`; ``--readings``,
``--max-iter`` and ``--seed`` must lie in the ranges of :data:`MIN_READINGS` ...
:data:`MAX_SEED` (``--max-iter 0`` would write an untrained profile, about 4x worse than the
linear one). Errors raise :class:`~ias_gym.errors.InputError` (the ``ias-gym`` command
prints one line) before any training or writing, except the better-profile check, which
needs the new error.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ias_gym.cli.args import HelpFormatter, overwrite_argument
from ias_gym.errors import IasGymError, InputError
from ias_gym.glove.calibration import DEFAULT_MAX_ITER, DEFAULT_READINGS
from ias_gym.glove.hand import JOINT_NAMES, PersonParams, hand_points
from ias_gym.glove.ids import ID_RULE, check_id
from ias_gym.glove.profile import (
    DEFAULT_GLOVE_ID,
    Profile,
    ProfileError,
    load_profile,
    save_profile,
    write_bytes_atomic,
)

if TYPE_CHECKING:
    from ias_gym.glove.training import CalibrationRun

#: Accepted ``--readings``: fewer leave too few held-out pinch poses for the figure; more
#: than a million is not a calibration session (memory and hours of training).
MIN_READINGS, MAX_READINGS = 100, 1_000_000
#: Accepted ``--max-iter`` (L-BFGS iterations per network): 0 would save untrained weights.
MAX_ITER = 100_000
#: Largest ``--seed`` (numpy seeds are non-negative).
MAX_SEED = 2**32 - 1


def pick_pinch_pose(run: CalibrationRun) -> int:
    """Index into ``run.held_out`` of the pinch pose drawn in the figure.

    The pose whose linear fingertip-gap error is the median over the held-out pinch poses:
    a typical pose, not the worst one.
    """
    from ias_gym.glove.calibration import gap_errors_mm

    held = run.held_out
    idx = np.flatnonzero(held.pinch)
    if idx.size == 0:
        raise ValueError("the held-out readings contain no pinch pose")
    pred = run.models["linear"].predict(held.psi[idx])
    err = gap_errors_mm(held.theta[idx], pred, run.person)
    return int(idx[np.argsort(err)[len(err) // 2]])


def plot_pinch_calibration(run: CalibrationRun, path: Path) -> Path:
    """Write the Fig. 7-style PNG: truth vs linear (a) and vs ANN (b) in a pinch pose."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ias_gym.glove.calibration import gap_errors_mm

    k = pick_pinch_pose(run)
    held = run.held_out
    truth = held.theta[k]
    fig, axes = plt.subplots(
        1, 2, figsize=(10, 5), sharex=True, sharey=True, constrained_layout=True
    )
    panels = (("linear", "(a) Linear combination"), ("ann", "(b) Using the trained ANN"))
    index_names = ("index_mcp", "index_pip", "index_dip", "thumb_cmc", "thumb_flexion")
    rows = [JOINT_NAMES.index(n) for n in index_names]
    lowest = 0.0  # most palmar point drawn [mm]
    for ax, (name, title) in zip(axes, panels, strict=True):
        est = run.models[name].predict(held.psi[k])
        for theta, style, label in (
            (truth, {"color": "0.55", "lw": 6, "alpha": 0.6}, "hand (truth)"),
            (est, {"color": "C3" if name == "linear" else "C0", "lw": 2}, "calibrated model"),
        ):
            index, thumb = hand_points(theta, run.person)
            lowest = max(lowest, 1e3 * index[:, 1].max(), 1e3 * thumb[:, 1].max())
            for pts, lab in ((index, label), (thumb, None)):
                ax.plot(1e3 * pts[:, 0], 1e3 * pts[:, 1], "-o", ms=4, label=lab, **style)
        base = run.person.thumb_base
        ax.plot([-70, 0], [0, 0], color="0.8", lw=8, zorder=0)  # back of the hand
        ax.plot([-70, 1e3 * base[0]], [1e3 * base[1]] * 2, color="0.8", lw=8, zorder=0)
        gap = float(gap_errors_mm(truth, est, run.person))
        err = np.rad2deg(est[rows] - truth[rows])
        ax.set_title(f"{title}\nfingertip gap error {gap:.1f} mm", fontsize=10)
        ax.text(
            0.02,
            0.97,
            "joint errors [deg]\n"
            + "\n".join(f"{n:<14}{e:+6.1f}" for n, e in zip(index_names, err, strict=True)),
            transform=ax.transAxes,
            fontsize=7,
            va="top",
            family="monospace",
        )
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        ax.set_xlabel("distal x [mm]")
    # Palmar down (a side view, back of the hand on top); room above it for the text.
    # The y axis is shared: set the limits and invert it once.
    axes[0].set_ylim(lowest + 10, -38)
    axes[0].set_ylabel("palmar y [mm]")
    axes[1].legend(loc="upper right", fontsize=8, framealpha=0.9)
    fig.suptitle(
        f"Calibration result in a pinch pose (paper Fig. 7), person {run.person.person_id} "
        f"(hand scale {run.person.hand_scale:.2f}), held-out pose",
        fontsize=10,
    )
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=120)
    plt.close(fig)
    return write_bytes_atomic(path, buf.getvalue())


def calibration_summary(run: CalibrationRun) -> dict[str, Any]:
    """The JSON summary of a run (the six headline keys first)."""
    m = run.metrics
    summary: dict[str, Any] = {
        "ann_rms_deg": m["ann"].rms_deg,
        "linear_rms_deg": m["linear"].rms_deg,
        "ann_pinch_rms_deg": m["ann"].pinch_rms_deg,
        "linear_pinch_rms_deg": m["linear"].pinch_rms_deg,
        "ann_pinch_gap_mm": m["ann"].pinch_gap_mm,
        "linear_pinch_gap_mm": m["linear"].pinch_gap_mm,
    }
    for name in ("paper_ann", "linear_free"):
        summary[f"{name}_rms_deg"] = m[name].rms_deg
        summary[f"{name}_pinch_rms_deg"] = m[name].pinch_rms_deg
        summary[f"{name}_pinch_gap_mm"] = m[name].pinch_gap_mm
    summary["train_seconds"] = run.report.seconds
    summary["person"] = run.person.person_id
    summary["n_held_out"] = m["ann"].n
    summary["n_held_out_pinch"] = m["ann"].n_pinch
    return summary


def _check_range(name: str, value: int, low: int, high: int) -> int:
    if not low <= value <= high:
        raise InputError(f"{name} must be in [{low}, {high}], got {value}")
    return value


def _writable_dir(out: Path) -> None:
    """Refuse an output folder that is a file or cannot be created or written."""
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} is a file, not a folder; pass a folder")
    existing = out
    while not existing.exists():  # the folder is created; its nearest parent must allow it
        existing = existing.parent
    if not existing.is_dir() or not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"--out {out}: cannot write in {existing}; pass a writable folder")


def _existing_profile(path: Path) -> Profile | None:
    """The profile at ``path``, or None if it cannot be read as one (nothing to keep)."""
    try:
        return load_profile(path)
    except ProfileError as exc:
        print(f"note: replacing {path}, which is not a usable profile ({exc})", file=sys.stderr)
        return None


def _calibrate(args: argparse.Namespace) -> int:
    person_id = check_id(args.person, "--person")
    glove_id = check_id(args.glove_id, "--glove-id")
    _check_range("--readings", args.readings, MIN_READINGS, MAX_READINGS)
    _check_range("--max-iter", args.max_iter, 1, MAX_ITER)
    _check_range("--seed", args.seed, 0, MAX_SEED)
    out = Path(args.out)
    _writable_dir(out)
    profile_target = out / f"profile_{person_id}.json"
    figure_target = out / f"calibration_{person_id}.png"
    overwrite = args.overwrite or args.force
    existing = [p for p in (profile_target, figure_target) if p.exists()]
    if existing and not overwrite:
        raise InputError(
            f"{', '.join(map(str, existing))} exist(s) already; pass --overwrite to replace "
            "(a profile with a lower held-out error than the new one is still kept unless "
            "--force), or choose another --out"
        )
    previous = _existing_profile(profile_target) if profile_target.exists() else None
    try:
        from ias_gym.glove.calibration import metrics_table
        from ias_gym.glove.training import calibrate_person
    except ImportError as exc:
        raise IasGymError(str(exc)) from exc
    person = PersonParams.sample(person_id)
    run = calibrate_person(
        person,
        seed=args.seed,
        n_readings=args.readings,
        glove_id=glove_id,
        max_iter=args.max_iter,
    )
    new_error = run.profile.held_out.rms_deg
    if previous is not None and previous.held_out.rms_deg < new_error and not args.force:
        raise InputError(
            f"kept {profile_target}: its held-out joint RMS {previous.held_out.rms_deg:.3f} deg "
            f"is better than the new calibration's {new_error:.3f} deg; pass --force to "
            "replace it anyway, or choose another --out"
        )
    try:
        profile_path = save_profile(run.profile, profile_target)
        figure_path = plot_pinch_calibration(run, figure_target)
    except OSError as exc:
        raise InputError(f"cannot write to {out}: {exc}") from exc
    held = run.metrics["ann"]
    print(
        f"person {person.person_id}: hand scale {person.hand_scale:.3f}, "
        f"{len(run.train)} training / {held.n} held-out readings ({held.n_pinch} pinch)"
    )
    print(f"ANN: {run.models['ann'].describe()}; trained in {run.report.seconds:.2f} s")
    labels = {
        "ann": "ANN (shipped)",
        "paper_ann": "ANN index 2-10-3",
        "linear": "linear",
        "linear_free": "linear, free poses",
    }
    print("held-out errors:")
    print(metrics_table({labels[k]: v for k, v in run.metrics.items()}))
    if previous is not None:
        print(
            f"replaced a profile with held-out joint RMS {previous.held_out.rms_deg:.3f} deg "
            f"by one with {new_error:.3f} deg"
        )
    print(f"wrote profile {profile_path}")
    print(f"wrote figure {figure_path}")
    if args.json:
        print(json.dumps(calibration_summary(run)))
    return 0


def _population(args: argparse.Namespace) -> int:
    from ias_gym.figures.population_histograms import person_rows, population_figure
    from ias_gym.glove.population import check_population
    from ias_gym.outputs import check_output_file

    n, seed = check_population(args.population, args.population_seed)
    if args.plot is not None:  # checked before any work
        check_output_file(args.plot, overwrite=args.overwrite, suffixes=(".png",))
    rows = person_rows(n, seed)
    if args.json:
        for row in rows:
            print(json.dumps(row))
    else:
        keys = ("hand_scale", "range_of_motion", "speed", "amplitude", "visual_delay")
        print(f"{'person':<20} " + " ".join(f"{k:>15}" for k in keys))
        for row in rows:
            print(f"{row['person_id']:<20} " + " ".join(f"{row[k]:>15.3f}" for k in keys))
    if args.plot is not None:
        population_figure(n, seed, Path(args.plot), overwrite=args.overwrite)
        print(f"wrote {args.plot}", file=sys.stderr)
    return 0


def add_glove_commands(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``calibrate`` and ``population`` to the ``ias-gym`` sub-commands
    (``parser.add_subparsers()``).

    Args:
        subparsers: the object ``parser.add_subparsers(...)`` returned; the parser sets
            ``run`` (``args -> exit code``, raising :class:`~ias_gym.errors.IasGymError` on
            an error) as its default.
    """
    population = subparsers.add_parser(
        "population",
        help="list (and plot) simulated persons drawn from the population",
        description="Draw N simulated persons with a population seed (the ids any --person "
        "takes; the same seed gives the same persons on every machine) and print their "
        "parameters: hand scale and range of motion [-], movement speed and amplitude "
        "factors [-], visual delay [s]; --json prints every parameter, one JSON object per "
        "person. The distributions and their sources: docs/population.md.",
        formatter_class=HelpFormatter,
    )
    population.add_argument(
        "--population", type=int, default=30, metavar="N", help="persons to draw (>= 1)"
    )
    population.add_argument(
        "--population-seed", type=int, default=0, metavar="S", help="seed of the draw (>= 0)"
    )
    population.add_argument("--json", action="store_true", help="one JSON object per person")
    population.add_argument("--plot", metavar="PNG", help="also write histograms to this file")
    overwrite_argument(population)
    population.set_defaults(run=_population)

    calibrate = subparsers.add_parser(
        "calibrate",
        help="calibrate the sensor glove for a (simulated) person: profile + Fig. 7",
        description="Record a simulated calibration session for a person, train the "
        "calibration Θ = f(Ψ) (eq. 1; ANN and the linear baseline), write "
        "DIR/profile_ID.json and DIR/calibration_ID.png (Fig. 7: a pinch pose, truth vs "
        "linear vs ANN) and print the held-out errors. Existing files are never replaced "
        "silently: see --overwrite and --force.",
    )
    calibrate.add_argument(
        "--person", required=True, metavar="ID", help=f"person id, e.g. p1 ({ID_RULE})"
    )
    calibrate.add_argument(
        "--seed",
        type=int,
        default=0,
        metavar="S",
        help=f"seeds the session, split and training, 0 to {MAX_SEED} (default: 0)",
    )
    calibrate.add_argument("--out", required=True, metavar="DIR", help="output directory")
    calibrate.add_argument(
        "--json", action="store_true", help="print one JSON object as the last line"
    )
    calibrate.add_argument(
        "--glove-id",
        default=DEFAULT_GLOVE_ID,
        metavar="ID",
        help=f"glove id stored in the profile, same rule as --person (default: {DEFAULT_GLOVE_ID})",
    )
    calibrate.add_argument(
        "--readings",
        type=int,
        default=DEFAULT_READINGS,
        metavar="N",
        help=f"readings in the session, 20%% held out; {MIN_READINGS} to {MAX_READINGS} "
        f"(default: {DEFAULT_READINGS})",
    )
    calibrate.add_argument(
        "--max-iter",
        type=int,
        default=DEFAULT_MAX_ITER,
        metavar="N",
        help=f"L-BFGS iterations per network, 1 to {MAX_ITER} (default: {DEFAULT_MAX_ITER})",
    )
    calibrate.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an existing profile_ID.json / calibration_ID.png in DIR, but keep a "
        "profile whose held-out joint RMS error is lower than the new one's (then nothing "
        "is written and the command fails)",
    )
    calibrate.add_argument(
        "--force",
        action="store_true",
        help="with or without --overwrite: replace the files even if the existing profile "
        "has a lower held-out error",
    )
    calibrate.set_defaults(run=_calibrate)

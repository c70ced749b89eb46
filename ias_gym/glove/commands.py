"""The ``ias-gym calibrate`` command: calibrate a simulated person's glove (paper 2.4, Fig. 7).

:func:`add_glove_commands` adds ``calibrate`` to the ``ias-gym`` parser's sub-commands::

    ias-gym calibrate --person ID [--seed S] --out DIR [--json]

It records a simulated calibration session for person ID (:class:`PersonParams` sampled from
the id), trains the calibration (:func:`~ias_gym.glove.training.calibrate_person`), writes
``DIR/profile_<ID>.json`` (the person's profile) and ``DIR/calibration_<ID>.png`` (Fig. 7 in
our terms: a held-out pinch pose, index finger and thumb as planar stick figures, the truth
against (a) the linear calibration and (b) the ANN), and prints the held-out errors. With
``--json`` the last line is one JSON object with ``ann_rms_deg``, ``linear_rms_deg`` (joint
RMS over all joints), ``ann_pinch_rms_deg``, ``linear_pinch_rms_deg`` (pinch poses),
``ann_pinch_gap_mm``, ``linear_pinch_gap_mm`` (fingertip gap error in pinch), and more.
Torch and matplotlib are imported when the command runs, so ``--help`` stays fast.
"""

from __future__ import annotations

import argparse
import io
import json
import re
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ias_gym.glove.calibration import DEFAULT_MAX_ITER, DEFAULT_READINGS
from ias_gym.glove.hand import JOINT_NAMES, PersonParams, hand_points
from ias_gym.glove.profile import DEFAULT_GLOVE_ID, save_profile, write_bytes_atomic

if TYPE_CHECKING:
    from ias_gym.glove.training import CalibrationRun

#: Exit code of a handled error.
EXIT_ERROR = 1
_ID_PATTERN = re.compile(r"^[A-Za-z0-9_.-]{1,64}$")


def _fail(message: str) -> int:
    print(f"error: {message}", file=sys.stderr)
    return EXIT_ERROR


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


def _calibrate(args: argparse.Namespace) -> int:
    if not _ID_PATTERN.match(args.person):
        return _fail(f"--person must be 1-64 letters, digits, '.', '_' or '-', got {args.person!r}")
    if args.readings < 100:
        return _fail(f"--readings must be at least 100, got {args.readings}")
    try:
        from ias_gym.glove.calibration import metrics_table
        from ias_gym.glove.training import calibrate_person
    except ImportError as exc:
        return _fail(str(exc))
    out = Path(args.out)
    person = PersonParams.sample(args.person)
    run = calibrate_person(
        person,
        seed=args.seed,
        n_readings=args.readings,
        glove_id=args.glove_id,
        max_iter=args.max_iter,
    )
    try:
        profile_path = save_profile(run.profile, out / f"profile_{args.person}.json")
        figure_path = plot_pinch_calibration(run, out / f"calibration_{args.person}.png")
    except OSError as exc:
        return _fail(f"cannot write to {out}: {exc}")
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
    print(f"wrote profile {profile_path}")
    print(f"wrote figure {figure_path}")
    if args.json:
        print(json.dumps(calibration_summary(run)))
    return 0


def add_glove_commands(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``calibrate`` to the ``ias-gym`` sub-commands (``parser.add_subparsers()``)."""
    calibrate = subparsers.add_parser(
        "calibrate",
        help="calibrate the sensor glove for a (simulated) person: profile + Fig. 7",
        description="Record a simulated calibration session for a person, train the "
        "calibration Θ = f(Ψ) (eq. 1; ANN and the linear baseline), write "
        "DIR/profile_ID.json and DIR/calibration_ID.png (Fig. 7: a pinch pose, truth vs "
        "linear vs ANN) and print the held-out errors.",
    )
    calibrate.add_argument("--person", required=True, metavar="ID", help="person id, e.g. p1")
    calibrate.add_argument(
        "--seed", type=int, default=0, metavar="S", help="seeds the session, split and training"
    )
    calibrate.add_argument("--out", required=True, metavar="DIR", help="output directory")
    calibrate.add_argument(
        "--json", action="store_true", help="print one JSON object as the last line"
    )
    calibrate.add_argument(
        "--glove-id", default=DEFAULT_GLOVE_ID, metavar="ID", help="glove id stored in the profile"
    )
    calibrate.add_argument(
        "--readings",
        type=int,
        default=DEFAULT_READINGS,
        metavar="N",
        help="readings in the session (20%% held out)",
    )
    calibrate.add_argument(
        "--max-iter",
        type=int,
        default=DEFAULT_MAX_ITER,
        metavar="N",
        help="L-BFGS iterations per network",
    )
    calibrate.set_defaults(run=_calibrate)

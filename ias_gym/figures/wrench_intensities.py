"""Figure 8 of the paper: wrench intensities of the pen-sliding skill over time."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ias_gym.figures._io import save_png_atomic, write_csv_atomic
from ias_gym.grasp.internal_forces import Cone
from ias_gym.grasp.pen_skill import N_FINGERS, PenSkillParams, wrench_intensities
from ias_gym.outputs import prepare_output_dir

CSV_NAME = "wrench_intensities.csv"
PNG_NAME = "wrench_intensities.png"


def wrench_intensity_table(
    params: PenSkillParams = PenSkillParams(), cone: Cone = "box", samples: int = 401
) -> np.ndarray:
    """``(samples, 13)`` array: t [s] over [t_0, t_4], then c_1..c_12 [N] (paper numbering).

    The schedule is defined on [t_0, t_4): at t_4 itself no finger slides any more and the
    intensities jump to those of a static grasp, which is not part of the skill. So the
    last row, labelled t_4, holds the left limit there: the intensities at the last
    floating-point time before t_4 (the end of phase 4).

    Args:
        params: the sliding skill's parameters.
        cone: friction cone of the internal-force problem (``"box"`` or ``"exact"``).
        samples: number of rows (>= 2), evenly spaced from t_0 to t_4 [s].

    Raises:
        ValueError: ``samples`` < 2.
    """
    if samples < 2:
        raise ValueError(f"samples must be >= 2 (t_0 and t_4), got {samples}")
    t = np.linspace(params.phase_times[0], params.duration, samples)
    at = t.copy()
    at[-1] = np.nextafter(params.duration, -np.inf)  # the left limit: phase 4 still on
    return np.column_stack([t, wrench_intensities(at, params, cone=cone)])


def write_wrench_intensity_figure(
    out_dir: Path,
    cone: Cone = "box",
    params: PenSkillParams = PenSkillParams(),
    *,
    overwrite: bool = False,
) -> tuple[Path, Path]:
    """Write ``wrench_intensities.csv`` and ``wrench_intensities.png`` into ``out_dir``.

    Args:
        out_dir: output directory (created if missing; checked before the computation).
        cone: friction cone of the internal-force problem (``"box"`` or ``"exact"``).
        params: the sliding skill's parameters.
        overwrite: replace existing output files.

    Returns:
        The CSV and PNG paths.

    Raises:
        InputError: ``out_dir`` cannot be created or written.
        OutputExistsError: an output file exists and ``overwrite`` is false.
    """
    out_dir = prepare_output_dir(out_dir, (CSV_NAME, PNG_NAME), overwrite=overwrite)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = wrench_intensity_table(params, cone)
    header = ["t"] + [f"c{i}" for i in range(1, 3 * N_FINGERS + 1)]
    csv_path = write_csv_atomic(out_dir / CSV_NAME, header, table, overwrite=overwrite)

    t, c = table[:, 0], table[:, 1:]
    fig, axes = plt.subplots(N_FINGERS, 1, sharex=True, figsize=(8.5, 8), constrained_layout=True)
    labels = ("normal", "along pen (x)", "lateral (z)")
    for k, ax in enumerate(axes):
        for j, label in enumerate(labels):
            idx = 3 * k + j
            ax.plot(t, c[:, idx], label=f"$c_{{{idx + 1}}}$ {label}")
        for boundary in params.phase_times[1:-1]:
            ax.axvline(boundary, color="0.7", lw=0.8, ls="--")
        ax.axvspan(params.phase_times[k], params.phase_times[k + 1], color="C3", alpha=0.06)
        ax.set_ylabel(f"finger {k + 1} [N]")
        # outside the axes: inside, they hid the 0.1 N normal traces of fingers 1 and 4
        ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=7, frameon=False)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("t [s]  (shaded: this finger slides; the schedule ends at t = 4 s)")
    fig.suptitle(
        f"Wrench intensities of the sliding skill (paper Fig. 8)\n{cone} cone, "
        f"mu = {params.mu}, f0 = {params.f0} N, mg = {params.weight} N",
        fontsize=10,
    )
    png_path = save_png_atomic(fig, out_dir / PNG_NAME, overwrite=overwrite)
    plt.close(fig)
    return csv_path, png_path

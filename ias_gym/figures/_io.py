"""Writing figure data: files replaced atomically, so a reader never sees half a file, and
never replaced unless asked (:mod:`ias_gym.outputs`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ias_gym.outputs import atomic_output


def write_csv_atomic(
    path: Path,
    header: Sequence[str],
    rows: ArrayLike,
    fmt: str = "%.9g",
    *,
    overwrite: bool = False,
) -> Path:
    """Write ``rows`` under a one-line ``header`` to ``path`` via a temporary file + rename.

    Raises:
        OutputExistsError: ``path`` exists and ``overwrite`` is false.
    """
    with atomic_output(path, overwrite=overwrite) as tmp:
        np.savetxt(
            tmp, np.asarray(rows), delimiter=",", header=",".join(header), comments="", fmt=fmt
        )
    return path


def save_png_atomic(fig: object, path: Path, dpi: int = 120, *, overwrite: bool = False) -> Path:
    """Save a matplotlib figure to ``path`` via a temporary file + rename.

    Raises:
        OutputExistsError: ``path`` exists and ``overwrite`` is false.
    """
    with atomic_output(path, overwrite=overwrite) as tmp:
        fig.savefig(tmp, dpi=dpi)  # type: ignore[attr-defined]
    return path

"""Writing figure data: CSV files replaced atomically, so a reader never sees half a file."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike


def write_csv_atomic(path: Path, header: Sequence[str], rows: ArrayLike, fmt: str = "%.9g") -> Path:
    """Write ``rows`` under a one-line ``header`` to ``path`` via a temporary file + rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; a figure's data is not secret
        with os.fdopen(fd, "w") as f:
            np.savetxt(
                f, np.asarray(rows), delimiter=",", header=",".join(header), comments="", fmt=fmt
            )
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def save_png_atomic(fig: object, path: Path, dpi: int = 120) -> Path:
    """Save a matplotlib figure to ``path`` via a temporary file + rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp.png")
    try:
        fig.savefig(tmp, dpi=dpi)  # type: ignore[attr-defined]
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path

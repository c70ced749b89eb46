"""Reference values written out from the paper and docs/NOTES.md, independently of the package."""

from __future__ import annotations

import numpy as np

PEN_RADIUS = 0.01  # r [m]
PEN_PHI = (0.03, 0.02, 0.02, 0.03)  # l_i [m], paper section 4.2


def eq16(phi: tuple[float, ...] = PEN_PHI, r: float = PEN_RADIUS) -> np.ndarray:
    """W of eq. (16) as corrected in docs/NOTES.md (6 x 12), entry by entry."""
    p1, p2, p3, p4 = phi
    return np.array(
        [
            [0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0],
            [-1, 0, 0, 1, 0, 0, 1, 0, 0, -1, 0, 0],
            [0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1],
            [0, 0, r, 0, 0, -r, 0, 0, -r, 0, 0, r],
            [0, 0, p1, 0, 0, p2, 0, 0, -p3, 0, 0, -p4],
            [p1, -r, 0, -p2, r, 0, p3, r, 0, -p4, -r, 0],
        ],
        dtype=float,
    )

"""The pen's friction coefficient as the fingertips show it (beyond the paper).

The grip-transform expert scales a skill's squeeze to the demonstrated margin with the
coefficient read here (docs/controller.md, "The pen's friction"); the slip speeds it needs
come from :func:`~ias_gym.baselines.grip_transform_terms.slip_speeds`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ias_gym.grasp.grasp_margin import tangential_ratios

FloatArray = NDArray[np.float64]
NDArrayBool = np.ndarray


@dataclass
class FrictionEstimate:
    """The pen's friction coefficient as the tips show it (beyond the paper).

    A contact force never leaves its friction cone, so a tip's ratio of tangential to normal
    force reads at most the coefficient, and a tip on its cone reads the coefficient itself
    (:func:`~ias_gym.grasp.grasp_margin.tangential_ratios`). Two readings of "on its cone":

    - **a slide**: the tip's slip speed
      (:func:`~ias_gym.baselines.grip_transform_terms.slip_speeds`) stays above a threshold for
      ``duration`` seconds in a row (sensor noise fakes a slip for a step, rarely for
      several); the reading is the mean ratio over the slide;
    - **a ceiling** (``plateau`` > 0): the tip's ratio comes back to its highest value so far,
      within ``tolerance`` of it, on steps that add up to ``plateau`` seconds, and never
      rises above it meanwhile. A tip whose demand exceeds its cone is held at the cone by
      friction, its ratio pinned there while the tip creeps too slowly for a slide (a
      finger with sticking joints); a sticking tip's ratio follows the load and comes back
      to one value within 0.2 % rarely. The reading is that ceiling.

    The estimate is the largest reading so far; 0 until there is one.
    """

    duration: float  # [s]
    plateau: float = 0.0  # [s] (0: no ceiling reading)
    tolerance: float = 0.002  # [-] relative
    count: FloatArray | None = None  # control steps each tip has slid in a row
    total: FloatArray | None = None  # their ratios' sum [-]
    level: FloatArray | None = None  # each tip's highest ratio so far [-]
    hits: FloatArray | None = None  # steps at it since it last rose
    value: float = 0.0

    def update(self, c: FloatArray, sliding: NDArrayBool, n_min: float, dt: float) -> float:
        """Take one control step (``dt`` [s]): the measured intensities ``(3 k,)`` [N] and
        the tips that slide ``(k,)``; a tip counts while pressed with at least ``n_min``
        [N]. Returns the estimate [-] (0: none yet)."""
        ratios = tangential_ratios(c)
        pressed = (c[0::3] >= n_min) & np.isfinite(ratios)
        now = sliding & pressed
        count = np.zeros(len(now)) if self.count is None else self.count
        total = np.zeros(len(now)) if self.total is None else self.total
        self.count = np.where(now, count + 1.0, 0.0)
        self.total = np.where(now, total + ratios, 0.0)  # a NaN ratio is never taken
        done = self.count * dt >= self.duration - 1e-9
        if done.any():
            self.value = max(self.value, float(np.max(self.total[done] / self.count[done])))
        if self.plateau > 0:
            self._ceiling(np.where(pressed, ratios, 0.0), pressed, dt)
        return self.value

    def _ceiling(self, ratios: FloatArray, pressed: NDArrayBool, dt: float) -> None:
        """The ceiling reading of one step (see the class docstring)."""
        level = np.zeros(len(ratios)) if self.level is None else self.level
        hits = np.zeros(len(ratios)) if self.hits is None else self.hits
        rise = pressed & (ratios > level * (1 + self.tolerance))
        at = pressed & ~rise & (ratios >= level * (1 - self.tolerance))
        self.level = np.where(rise, ratios, level)
        self.hits = np.where(rise, 1.0, hits + at)
        done = self.hits * dt >= self.plateau - 1e-9
        if done.any():
            self.value = max(self.value, float(np.max(self.level[done])))

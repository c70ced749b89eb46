"""The DTW recogniser (``"dtw"``, the baseline of :mod:`ias_gym.assist.recognition`).

1-nearest-neighbour open-end dynamic time warping of the session so far against every stored
session (:func:`open_end_dtw_cost`, dtaidistance's C DTW), recomputed every
:data:`DTW_STRIDE` steps on the session sub-sampled by the same stride, and its constants.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from ias_gym.assist.recognition import LibraryRecogniser, LibrarySession

FloatArray = NDArray[np.float64]

#: DTW: costs are recomputed every this many control steps on the session sub-sampled by it.
DTW_STRIDE = 5
#: DTW: the Sakoe-Chiba window [samples of the sub-sampled session]: 0.4 s, the largest
#: shift a person's delay (<= 0.15 s) and speed (+-15 % over <= 2 s) make.
DTW_WINDOW = 8
#: DTW: the time stretch and amplitude factor of a template's scale, and the floor of the
#: scale (feature units squared: (0.1 x FEATURE_SCALE)^2, sensor-noise sized).
DTW_SELF_STRETCH = 1.1
DTW_COST_FLOOR = 0.01


def open_end_dtw_cost(query: FloatArray, template: FloatArray, window: int | None = None) -> float:
    """Mean squared cost per query sample of the open-end DTW of ``query`` on ``template``.

    The query (a partial session) is aligned with the best prefix of the template (a full
    session): the smallest entry of the last row of dtaidistance's accumulated-cost matrix
    (``dtw_ndim.warping_paths``, squared Euclidean inner distance; its entries are the roots
    of the paths' summed costs). With a ``window`` the template is first cut to
    ``len(query) + window`` samples and the path kept in dtaidistance's band (Sakoe-Chiba,
    widened by the length difference): an open end alone lets the query's last samples
    stall on one template sample for ever, so a session that holds still would match every
    skill "not started yet". (dtaidistance's psi relaxation would give the open end in one
    call, but combined with a window its C code returns garbage in 2.5.1: 1e-161 or NaN.)

    Args:
        query: ``(n, d)`` samples.
        template: ``(m, d)`` samples.
        window: the largest shift between the two in samples, or ``None`` (unconstrained).

    Returns:
        ``distance^2 / n``.
    """
    from dtaidistance import dtw_ndim  # the [assist] extra

    q = np.ascontiguousarray(query, dtype=np.float64)
    t = template if window is None else template[: len(q) + window]
    t = np.ascontiguousarray(t, dtype=np.float64)
    _, paths = dtw_ndim.warping_paths(q, t, window=window, use_c=True)
    d = float(np.min(paths[-1, 1:]))  # inf outside the band
    return d * d / len(q)


class DTWRecogniser(LibraryRecogniser):
    """1-nearest-neighbour open-end DTW on the stored sessions (the baseline).

    A skill's evidence is ``-cost / tau``: its nearest template's cost (the
    :func:`open_end_dtw_cost` of the session so far on the template, both sub-sampled by
    :data:`DTW_STRIDE`, window :data:`DTW_WINDOW`) over the temperature ``tau``, a right
    match's typical cost (the median leave-one-person-out score times the median template
    scale). The novelty score is the smallest cost relative to its template's scale: the
    cost of the template's own motion performed 10 % larger and slower, plus
    :data:`DTW_COST_FLOOR`. Another person misses a template by a share of its motion, and
    a fast see-saw's right match costs far more than a still hold's, so raw costs would
    need a threshold per skill.

    Args:
        sessions: the library.

    Raises:
        InputError: empty library, or no skill performed by two persons (no calibration).
    """

    method = "dtw"

    def _fit_class(self, name: str) -> None:
        if not hasattr(self, "_scales"):
            self._scales: dict[int, float] = {}
        for s in self._classes[name]:
            self._scale(s)  # 1-NN: the sessions (and their cost scales) are the model

    def _reset_state(self) -> None:
        pass  # the costs are recomputed from the whole session so far

    def _costs(
        self, query: FloatArray, classes: Mapping[str, Sequence[LibrarySession]]
    ) -> tuple[dict[str, float], float]:
        """Each skill's nearest-template cost and the novelty score (the smallest cost
        relative to its template's scale)."""
        costs: dict[str, float] = {}
        novelty = math.inf
        for name, sessions in classes.items():
            best = math.inf
            for s in sessions:
                cost = open_end_dtw_cost(query, s.features[::DTW_STRIDE], DTW_WINDOW)
                best = min(best, cost)
                novelty = min(novelty, cost / self._scale(s))
            costs[name] = best
        return costs, novelty

    def _scale(self, s: LibrarySession) -> float:
        """The cost a 10 % larger and slower performance of ``s``'s motion has on it."""
        key = id(s)
        if key not in self._scales:
            t = s.features[::DTW_STRIDE]
            n = len(t)
            stretched = np.stack(
                [np.interp(np.arange(n) / DTW_SELF_STRETCH, np.arange(n), c) for c in t.T], axis=1
            )
            self._scales[key] = DTW_COST_FLOOR + open_end_dtw_cost(
                DTW_SELF_STRETCH * stretched, t, DTW_WINDOW
            )
        return self._scales[key]

    def _from_costs(
        self, costs: Mapping[str, float], novelty: float
    ) -> tuple[dict[str, float], float]:
        # a right match's typical raw cost: the median leave-one-out (relative) score times
        # the median template scale; 1 while the library is being calibrated
        tau = 1.0
        if self._loo:
            tau = max(float(np.median(self._loo) * np.median(list(self._scales.values()))), 1e-9)
        return {k: -c / tau for k, c in costs.items()}, novelty

    def _evidence(self) -> tuple[dict[str, float], float] | None:
        if (len(self._feats) - 1) % DTW_STRIDE:
            return None  # recomputed on the stride's grid only
        query = np.stack(self._feats[::DTW_STRIDE])
        return self._from_costs(*self._costs(query, self._classes))

    def _batch_evidence(
        self,
        feats: FloatArray,
        times: FloatArray,
        classes: Mapping[str, Sequence[LibrarySession]],
        refit: str | None = None,
    ) -> tuple[dict[str, float], float]:
        del times, refit  # DTW needs neither: its sessions are the model
        return self._from_costs(*self._costs(feats[::DTW_STRIDE], classes))

"""The phase recogniser (``"phase"`` of :mod:`ias_gym.assist.recognition`).

A phase-aware probabilistic model: each skill a mean trajectory and a variance over its
phase (:class:`PhaseModel`, :func:`fit_phase_model`), a grid of delay/speed hypotheses per
skill on line (:class:`PhaseRecogniser`), and the model's constants.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ias_gym.assist.recognition import LibraryRecogniser, LibrarySession
from ias_gym.assist.recognition_features import FEATURE_NAMES, FEATURE_T0

FloatArray = NDArray[np.float64]

#: Phase model: up to this time [s] the phase is the time (:data:`FEATURE_T0`).
PHASE_T0 = FEATURE_T0
#: Phase model: the delay [s] and speed [-] hypotheses of a skill's own motion.
PHASE_DELAYS = np.linspace(0.0, 0.2, 5)
PHASE_SPEEDS = np.linspace(0.8, 1.2, 9)
#: Phase model: the floor of each feature's standard deviation (feature units, i.e. a
#: tenth of FEATURE_SCALE) and the log-likelihood's tempering (one independent frame per
#: 10 control steps, ~0.1 s: consecutive frames of the smooth motion are far from independent).
PHASE_SIGMA_FLOOR = 0.1
PHASE_TEMPER = 0.1
#: Phase model: the weight [sessions] of the variance prior (fit_phase_model).
PHASE_PRIOR_WEIGHT = 2.0
#: Phase model: the phase grid's step [s] (one control step).
PHASE_DT = 0.01


@dataclass(frozen=True, eq=False)
class PhaseModel:
    """One skill over its phase: the mean and standard deviation of each feature.

    Attributes:
        mean: ``(G, 8)`` mean features on the phase grid (step :data:`PHASE_DT`, from 0).
        std: ``(G, 8)`` standard deviations (>= :data:`PHASE_SIGMA_FLOOR`).
    """

    mean: FloatArray
    std: FloatArray

    @functools.cached_property
    def inv_std(self) -> FloatArray:
        """``(G, 8)`` 1 / std."""
        return 1.0 / self.std

    @functools.cached_property
    def log_norm(self) -> FloatArray:
        """``(G,)`` the Gaussian's log normaliser, ``sum_d log(2 pi std_d^2)``."""
        return np.log(2.0 * np.pi * self.std**2).sum(axis=-1)


def _hypotheses() -> tuple[FloatArray, FloatArray]:
    d, v = np.meshgrid(PHASE_DELAYS, PHASE_SPEEDS, indexing="ij")
    return d.ravel(), v.ravel()


def phase_of(time_s: FloatArray, delay: FloatArray, speed: FloatArray) -> FloatArray:
    """The phase [s] of episode times under delay/speed hypotheses.

    Up to :data:`PHASE_T0` the phase is the time (the shared pinch-lift); then it waits
    ``delay`` [s] and runs at ``speed`` [-].

    Args:
        time_s: ``(T,)`` times [s].
        delay, speed: ``(H,)`` hypotheses.

    Returns:
        ``(H, T)`` phases [s].
    """
    t = np.asarray(time_s, dtype=np.float64)[None, :]
    d, v = np.asarray(delay)[:, None], np.asarray(speed)[:, None]
    return np.where(t <= PHASE_T0, t, PHASE_T0 + np.maximum(t - PHASE_T0 - d, 0.0) * v)


def _time_of(phase: FloatArray, delay: float, speed: float) -> FloatArray:
    """Inverse of :func:`phase_of` for one hypothesis (the first time a phase is reached)."""
    p = np.asarray(phase, dtype=np.float64)
    return np.where(p <= PHASE_T0, p, PHASE_T0 + delay + (p - PHASE_T0) / speed)


def _resample(s: LibrarySession, times: FloatArray) -> FloatArray:
    """``s``'s features at ``times`` (linear, held beyond its ends): ``(len(times), 8)``."""
    return np.stack(
        [np.interp(times, s.time_s, s.features[:, j]) for j in range(s.features.shape[1])],
        axis=1,
    )


def fit_phase_model(
    sessions: Sequence[LibrarySession],
    prior_var: FloatArray | None = None,
    iterations: int = 2,
) -> PhaseModel:
    """Fit a skill's :class:`PhaseModel`: align each session to the class mean, average.

    Starts from the sessions on their own time (delay 0, speed 1); each iteration picks,
    per session, the delay/speed hypothesis whose warped mean fits it best (least squares)
    and recomputes the mean and the variance on the phase grid. The variance of n sessions
    is shrunk towards ``prior_var`` with :data:`PHASE_PRIOR_WEIGHT` pseudo-sessions
    (``(n var + w prior) / (n + w)``, a conjugate prior's posterior mean), so that a skill
    learnt from one or two demonstrations gets a library-like spread, not the floor alone.

    Args:
        sessions: the skill's sessions (>= 1).
        prior_var: ``(G', 8)`` prior variance on the phase grid (held beyond its end), or
            ``None``: the sessions' own variance.
        iterations: alignment rounds.

    Returns:
        The model.
    """
    end = max(float(s.time_s[-1]) for s in sessions)
    # the grid reaches the phase of the slowest hypothesis' faster runs
    grid = np.arange(0.0, PHASE_T0 + (end - PHASE_T0) * PHASE_SPEEDS.max() + PHASE_DT, PHASE_DT)
    delays, speeds = _hypotheses()
    h_of = [(0.0, 1.0)] * len(sessions)
    model = PhaseModel(mean=np.zeros((len(grid), 8)), std=np.ones((len(grid), 8)))
    for it in range(iterations + 1):
        warped = np.stack(
            [_resample(s, _time_of(grid, d, v)) for s, (d, v) in zip(sessions, h_of, strict=True)]
        )
        var = warped.var(axis=0)
        if prior_var is not None:
            prior = prior_var[np.minimum(np.arange(len(grid)), len(prior_var) - 1)]
            n, w = len(sessions), PHASE_PRIOR_WEIGHT
            var = (n * var + w * prior) / (n + w)
        std = np.sqrt(var + PHASE_SIGMA_FLOOR**2)
        model = PhaseModel(mean=warped.mean(axis=0), std=std)
        if it == iterations or len(sessions) == 1:
            break
        new = []
        for s in sessions:
            ph = phase_of(s.time_s, delays, speeds)  # (H, T)
            idx = np.minimum(np.rint(ph / PHASE_DT).astype(int), len(grid) - 1)
            err = ((model.mean[idx] - s.features[None]) ** 2).sum(axis=(1, 2))
            best = int(np.argmin(err))
            new.append((float(delays[best]), float(speeds[best])))
        h_of = new
    return model


class PhaseRecogniser(LibraryRecogniser):
    """Phase-aware Gaussian model per skill with on-line phase hypotheses (the better method).

    For skill k and hypothesis h (delay, speed of the skill's own motion) the log-likelihood
    ``L[k, h] += PHASE_TEMPER * log N(x_t; mean_k(phase_h(t)), std_k(phase_h(t))^2)`` is
    accumulated frame by frame; the skill's evidence is ``log mean_h exp(L[k, h])`` (a
    uniform prior over the hypotheses) and the posterior is Bayes' rule over the skills. The
    novelty score is the mean squared Mahalanobis distance per feature and frame under the
    best skill and hypothesis.

    Args:
        sessions: the library.

    Raises:
        InputError: empty library, or no skill performed by two persons (no calibration).
    """

    method = "phase"

    def _fit_all(self) -> None:
        # The variance prior: the mean variance over the phase of the skills that several
        # persons performed, from a first fit without it; fixed from then on (add_skill
        # uses it as it is).
        self._prior_var: FloatArray | None = None
        self._models: dict[str, PhaseModel] = {}
        first = {k: fit_phase_model(v) for k, v in self._classes.items()}
        spread = [
            m.std**2 - PHASE_SIGMA_FLOOR**2
            for k, m in first.items()
            if len({s.group for s in self._classes[k]}) > 1
        ]
        if spread:
            g = min(len(v) for v in spread)
            self._prior_var = np.mean([v[:g] for v in spread], axis=0)
        for name in self._classes:
            self._fit_class(name)

    def _fit_class(self, name: str) -> None:
        self._models[name] = fit_phase_model(self._classes[name], self._prior_var)

    def _reset_state(self) -> None:
        self._delays, self._speeds = _hypotheses()
        k, h = len(self._classes), len(self._delays)
        self._loglik = np.zeros((k, h))
        self._maha = np.zeros((k, h))

    @staticmethod
    def _frame_terms(
        model: PhaseModel, x: FloatArray, phase: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """Per hypothesis (and frame): tempered log-likelihood and summed squared z."""
        idx = np.minimum(np.rint(phase / PHASE_DT).astype(int), len(model.mean) - 1)
        z2 = (((x - model.mean[idx]) * model.inv_std[idx]) ** 2).sum(axis=-1)
        ll = -0.5 * (z2 + model.log_norm[idx])
        return PHASE_TEMPER * ll, z2

    def _evidence(self) -> tuple[dict[str, float], float] | None:
        x = self._feats[-1]
        phase = phase_of(np.array([self._times[-1]]), self._delays, self._speeds)[:, 0]
        for i, name in enumerate(self._classes):
            ll, z2 = self._frame_terms(self._models[name], x, phase)
            self._loglik[i] += ll
            self._maha[i] += z2
        return self._summarise(list(self._classes), self._loglik, self._maha, len(self._feats))

    @staticmethod
    def _summarise(
        names: list[str], loglik: FloatArray, maha: FloatArray, n: int
    ) -> tuple[dict[str, float], float]:
        m = loglik.max(axis=1, keepdims=True)
        evidence = (m[:, 0] + np.log(np.exp(loglik - m).mean(axis=1))).tolist()
        k, h = np.unravel_index(int(np.argmax(loglik)), loglik.shape)
        novelty = float(maha[k, h]) / (n * len(FEATURE_NAMES))
        return dict(zip(names, evidence, strict=True)), novelty

    def _batch_evidence(
        self,
        feats: FloatArray,
        times: FloatArray,
        classes: Mapping[str, Sequence[LibrarySession]],
        refit: str | None = None,
    ) -> tuple[dict[str, float], float]:
        n = len(feats)
        phase = phase_of(times, self._delays, self._speeds)  # (H, T)
        loglik = np.zeros((len(classes), len(self._delays)))
        maha = np.zeros_like(loglik)
        for i, name in enumerate(classes):
            model = (
                fit_phase_model(classes[name], self._prior_var)
                if name == refit or name not in self._models
                else self._models[name]
            )
            ll, z2 = self._frame_terms(model, feats[None, :, :], phase)
            loglik[i], maha[i] = ll.sum(axis=1), z2.sum(axis=1)
        return self._summarise(list(classes), loglik, maha, n)

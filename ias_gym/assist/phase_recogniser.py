"""The phase recogniser (``"phase"`` of :mod:`ias_gym.assist.recognition`).

A phase-aware probabilistic model: each skill a mean trajectory and a variance over its
phase (:class:`PhaseModel`, :func:`fit_phase_model`), a grid of delay/speed hypotheses per
skill on line (:class:`PhaseRecogniser`), an operator who may switch from one skill to
another while performing it (:func:`switching_step`), and the model's constants.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ias_gym.assist.recognition import LibraryRecogniser, LibrarySession
from ias_gym.assist.recognition_features import FEATURE_NAMES, FEATURE_T0
from ias_gym.errors import InputError

FloatArray = NDArray[np.float64]

#: Phase model: up to this time [s] the phase is the time (:data:`FEATURE_T0`).
PHASE_T0 = FEATURE_T0
#: Phase model: the delay [s] and speed [-] hypotheses of a skill's own motion.
PHASE_DELAYS = np.linspace(0.0, 0.2, 5)
PHASE_SPEEDS = np.linspace(0.8, 1.2, 9)
#: Phase model: the floor of each feature's standard deviation (feature units, i.e. a
#: tenth of FEATURE_SCALE).
PHASE_SIGMA_FLOOR = 0.1
#: Phase model: the log-likelihood's tempering, the share of a frame that counts as an
#: independent observation (consecutive frames of the smooth motion are far from
#: independent); it sets how sure the posterior gets how fast. Fitted together with the
#: switch rate by ``train/fit_switch_rate.py`` (its report: docs/switch_rate_fit.json).
PHASE_TEMPER = 0.025
#: Phase model: the weight [sessions] of the variance prior (fit_phase_model).
PHASE_PRIOR_WEIGHT = 2.0
#: Phase model: the phase grid's step [s] (one control step).
PHASE_DT = 0.01
#: The probability per frame that the operator switches to another skill (a fixed-share
#: prior over the skills, :func:`switching_step`), fitted by ``train/fit_switch_rate.py``
#: (its report: docs/switch_rate_fit.json); 0: the skill of a session never changes.
PHASE_SWITCH_RATE = 1.107974365907566e-07


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


def switch_cost(rate: float, skills: int, temper: float = PHASE_TEMPER) -> float:
    """What a switch to one other skill costs in the novelty's units (summed squared z), as
    the tempered log-likelihood counts it: ``2 / temper x log((1 - rate) / (rate / (skills
    - 1)))``; ``inf`` when no switch is possible (``rate`` 0 or one skill)."""
    if rate <= 0.0 or skills < 2:
        return math.inf
    return 2.0 / temper * math.log((1.0 - rate) * (skills - 1) / rate)


def rate_of_cost(cost: float, skills: int, temper: float = PHASE_TEMPER) -> float:
    """The switch rate whose :func:`switch_cost` is ``cost`` (its inverse)."""
    odds = math.exp(0.5 * temper * cost) / (skills - 1)
    return 1.0 / (1.0 + odds)


def switching_step(
    log_alpha: FloatArray,
    path: FloatArray,
    ll: FloatArray,
    z2: FloatArray,
    rate: float,
    temper: float = PHASE_TEMPER,
) -> tuple[FloatArray, FloatArray]:
    """One frame of the switching model: the forward recursion of the skills' evidence and
    its best path's squared distance.

    Between two frames the operator stays with their skill with probability ``1 - rate``,
    or switches to one of the other ``K - 1`` skills (each equally likely) and keeps their
    delay and speed hypothesis (a person's timing is theirs, not the skill's): a fixed-share
    prior (Herbster and Warmuth, "Tracking the best expert", 1998). With ``rate`` 0 the
    recursion is the plain sum of each hypothesis' log-likelihoods.

    Args:
        log_alpha: ``(K, H)`` log of the forward variables so far (skill, hypothesis).
        path: ``(K, H)`` the summed squared z of the best path into each state so far, a
            switch counted as :func:`switch_cost`.
        ll: ``(K, H)`` the frame's tempered log-likelihoods.
        z2: ``(K, H)`` its summed squared z.
        rate: the switch probability per frame.
        temper: the likelihoods' tempering (for the switch's cost in the novelty).

    Returns:
        The new ``(log_alpha, path)``.
    """
    k = len(log_alpha)
    cost = switch_cost(rate, k, temper)
    if not math.isfinite(cost):
        return log_alpha + ll, path + z2
    m = log_alpha.max(axis=0, keepdims=True)
    e = np.exp(log_alpha - m)
    mixed = (1.0 - rate) * e + rate / (k - 1) * (e.sum(axis=0, keepdims=True) - e)
    # the best path from another skill: the smallest of the others in each column
    order = np.argsort(path, axis=0)
    first = np.take_along_axis(path, order[:1], axis=0)
    second = np.take_along_axis(path, order[1:2], axis=0)
    other = np.where(np.arange(k)[:, None] == order[:1], second, first)
    return m + np.log(mixed) + ll, np.minimum(path, other + cost) + z2


class PhaseRecogniser(LibraryRecogniser):
    """Phase-aware Gaussian model per skill with on-line phase hypotheses (the better method).

    For skill k and hypothesis h (delay, speed of the skill's own motion) each frame adds
    ``temper * log N(x_t; mean_k(phase_h(t)), std_k(phase_h(t))^2)`` to the forward
    variable of (k, h), which may also come from another skill's at the same hypothesis
    with the probability ``switch_rate`` (:func:`switching_step`); the skill's evidence is
    the sum over its hypotheses (a uniform prior over them) and the posterior is Bayes' rule
    over the skills. The novelty score is the mean squared Mahalanobis distance per feature
    and frame along the best path into the most probable skill and hypothesis.

    Args:
        sessions: the library.
        switch_rate: the probability per frame of a switch to another skill (default:
            the fitted :data:`PHASE_SWITCH_RATE`; 0: a session is one skill throughout).
        temper: the log-likelihood's tempering (default: the fitted :data:`PHASE_TEMPER`).

    Raises:
        InputError: empty library, no skill performed by two persons (no calibration), a
            switch rate outside [0, 1) or a temper outside (0, 1].
    """

    method = "phase"

    def __init__(
        self,
        sessions: Sequence[LibrarySession],
        switch_rate: float | None = None,
        temper: float | None = None,
    ) -> None:
        rate = PHASE_SWITCH_RATE if switch_rate is None else float(switch_rate)
        if not 0.0 <= rate < 1.0:
            raise InputError(f"switch_rate must lie in [0, 1), got {switch_rate!r}")
        t = PHASE_TEMPER if temper is None else float(temper)
        if not 0.0 < t <= 1.0:
            raise InputError(f"temper must lie in (0, 1], got {temper!r}")
        self.switch_rate, self.temper = rate, t
        super().__init__(sessions)

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
        self._log_alpha = np.zeros((k, h))
        self._path = np.zeros((k, h))

    def _frame_terms(
        self, model: PhaseModel, x: FloatArray, phase: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """Per hypothesis (and frame): tempered log-likelihood and summed squared z."""
        idx = np.minimum(np.rint(phase / PHASE_DT).astype(int), len(model.mean) - 1)
        z2 = (((x - model.mean[idx]) * model.inv_std[idx]) ** 2).sum(axis=-1)
        ll = -0.5 * (z2 + model.log_norm[idx])
        return self.temper * ll, z2

    def _evidence(self) -> tuple[dict[str, float], float] | None:
        x = self._feats[-1]
        phase = phase_of(np.array([self._times[-1]]), self._delays, self._speeds)[:, 0]
        terms = [self._frame_terms(self._models[name], x, phase) for name in self._classes]
        ll = np.stack([t[0] for t in terms])
        z2 = np.stack([t[1] for t in terms])
        if len(self._feats) == 1:
            self._log_alpha, self._path = ll, z2
        else:
            self._log_alpha, self._path = switching_step(
                self._log_alpha, self._path, ll, z2, self.switch_rate, self.temper
            )
        # keep the forward variables near 0 (only their differences count)
        self._log_alpha -= self._log_alpha.max()
        return self._summarise(list(self._classes), self._log_alpha, self._path, len(self._feats))

    @staticmethod
    def _summarise(
        names: list[str], log_alpha: FloatArray, path: FloatArray, n: int
    ) -> tuple[dict[str, float], float]:
        m = log_alpha.max(axis=1, keepdims=True)
        evidence = (m[:, 0] + np.log(np.exp(log_alpha - m).mean(axis=1))).tolist()
        k, h = np.unravel_index(int(np.argmax(log_alpha)), log_alpha.shape)
        novelty = float(path[k, h]) / (n * len(FEATURE_NAMES))
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
        ll = np.zeros((len(classes), len(self._delays), n))
        z2 = np.zeros_like(ll)
        for i, name in enumerate(classes):
            model = (
                fit_phase_model(classes[name], self._prior_var)
                if name == refit or name not in self._models
                else self._models[name]
            )
            ll[i], z2[i] = self._frame_terms(model, feats[None, :, :], phase)
        if not math.isfinite(switch_cost(self.switch_rate, len(classes), self.temper)):
            return self._summarise(list(classes), ll.sum(axis=2), z2.sum(axis=2), n)
        log_alpha, path = ll[:, :, 0], z2[:, :, 0]
        for t in range(1, n):
            log_alpha, path = switching_step(
                log_alpha, path, ll[:, :, t], z2[:, :, t], self.switch_rate, self.temper
            )
            log_alpha = log_alpha - log_alpha.max()
        return self._summarise(list(classes), log_alpha, path, n)

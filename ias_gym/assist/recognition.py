"""Intent recognition on a partial glove session (paper Flow 3) with unknown detection.

The assistant "identifies and anticipates the action the human operator wants to perform";
a recogniser turns the frames of a running glove session (:class:`SessionFrame`, one per
control step) into a :class:`Posterior` over the skills of a library plus ``"unknown"``,
updated at every step. Two recognisers share one interface (:class:`Recogniser`):

- :class:`DTWRecogniser` (``"dtw"``, the baseline): 1-nearest-neighbour open-end dynamic time
  warping of the session so far against every stored session (dtaidistance's C DTW with the
  psi relaxation on the template's end, so a partial session is matched against the best
  prefix of a full template). Costs are recomputed every :data:`DTW_STRIDE` steps on the
  session sub-sampled by the same stride (20 Hz); between, the last posterior is kept.
- :class:`PhaseRecogniser` (``"phase"``): a phase-aware probabilistic model. Each skill is a
  mean trajectory and a variance over its phase, learnt from its sessions after aligning
  each to the class mean (delay and speed of the skill's own motion); on line, a grid of
  delay/speed hypotheses per skill accumulates the Gaussian log-likelihood of every frame
  (tempered for the frames' correlation), and the posterior is Bayes' rule over the skills
  with the hypotheses marginalised.

Unknown detection (both): a novelty score of the session (DTW: the nearest template's mean
cost per sample; phase: the mean squared Mahalanobis distance per feature under the best
skill and hypothesis) is compared with the library's own leave-one-person-out scores (every
stored session scored against the library without its person's sessions of that skill):
the threshold is their 95 % quantile, where ``p(unknown) = 0.5``, and ``p(unknown)`` is 0.01
at their median (a logistic in the log score). No number is tuned per skill.

On-line acquisition: :meth:`Recogniser.add_skill` adds the sessions of a new (or known)
skill: DTW stores them as templates, the phase model fits that one skill's mean and
variance; the other skills and the scores already computed stay as they are, only the new
sessions' leave-one-out scores join the pool. :func:`acquire_skill` stores the session in
the :class:`~ias_gym.skills.SkillDB` (one transaction) before the recogniser learns it.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, TypeVar, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from ias_gym.assist.stream import SessionFrame, frames_from_skill
from ias_gym.errors import InputError
from ias_gym.glove.hand import joint_index
from ias_gym.glove.skills import SKILL_TIMINGS

if TYPE_CHECKING:
    from ias_gym.skills import Skill, SkillDB

FloatArray = NDArray[np.float64]

#: The posterior's key for "none of the stored skills".
UNKNOWN = "unknown"
#: The env whose sessions a library holds.
GLOVE_TASK = "IAS-GloveGrasp-v0"
#: Recogniser features: the wrist's calibrated angles (the operator's intent) and the pen's
#: pose (the object-level skill); its roll about its own axis is left out (the pinched pen
#: rolls between the pads by a person-dependent amount whatever the skill).
FEATURE_NAMES: tuple[str, ...] = (
    "theta_wrist_flexion",
    "theta_wrist_deviation",
    "theta_wrist_pronation",
    "pen_pitch",
    "pen_yaw",
    "pen_x",
    "pen_y",
    "pen_z",
)
#: Each feature is divided by its scale [rad or m]: 0.05 rad and 5 mm weigh alike.
FEATURE_SCALE = np.array([0.05, 0.05, 0.05, 0.05, 0.05, 0.005, 0.005, 0.005])
_THETA_IDX = np.array(
    [joint_index(j) for j in ("wrist_flexion", "wrist_deviation", "wrist_pronation")]
)
#: Episode time [s] from which skills may differ: the end of the scripted lift of the glove
#: protocol, the same for everyone (before it every session is the same reach-pinch-lift).
FEATURE_T0 = SKILL_TIMINGS.lift - SKILL_TIMINGS.reach
#: DTW: costs are recomputed every this many control steps on the session sub-sampled by it.
DTW_STRIDE = 5
#: DTW: the Sakoe-Chiba window [samples of the sub-sampled session]: 0.4 s, the largest
#: shift a person's delay (<= 0.15 s) and speed (+-15 % over <= 2 s) make.
DTW_WINDOW = 8
#: DTW: the time stretch and amplitude factor of a template's scale, and the floor of the
#: scale (feature units squared: (0.1 x FEATURE_SCALE)^2, sensor-noise sized).
DTW_SELF_STRETCH = 1.1
DTW_COST_FLOOR = 0.01
#: Leave-one-out quantile where p(unknown) = 0.5; p(unknown) = 0.01 at the median.
UNKNOWN_QUANTILE = 0.95
UNKNOWN_AT_MEDIAN = 0.01
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


def features(frame: SessionFrame) -> FloatArray:
    """The frame's raw feature vector (:data:`FEATURE_NAMES` / FEATURE_SCALE).

    Args:
        frame: one step of a session.

    Returns:
        ``(8,)`` dimensionless features.
    """
    raw = np.concatenate([frame.theta[_THETA_IDX], frame.pen_rpy[1:3], frame.pen_position])
    return raw.astype(np.float64) / FEATURE_SCALE


def feature_matrix(frames: Sequence[SessionFrame]) -> FloatArray:
    """``(T, 8)`` recogniser features of a session: :func:`features` relative to the frame at
    :data:`FEATURE_T0`, zero before it.

    Where a person's hand holds the pen (its lateral offset, a few mm) is theirs, not the
    skill's: the recognisers see how the features move from the end of the lift on, when
    the skills may begin, and nothing of the shared pinch-lift before.

    Raises:
        InputError: no frames.
    """
    if not frames:
        raise InputError("a session needs at least one frame")
    raw = np.stack([features(f) for f in frames])
    times = np.array([f.time_s for f in frames])
    return _relative(raw, times)


def _relative(raw: FloatArray, times: FloatArray) -> FloatArray:
    after = times >= FEATURE_T0 - 1e-9
    if not after.any():
        return np.zeros_like(raw)
    ref = raw[int(np.argmax(after))]
    return np.where(after[:, None], raw - ref, 0.0)


class Posterior(Mapping[str, float]):
    """Probabilities of the stored skills and of ``"unknown"``, summing to 1.

    Args:
        probabilities: name -> probability (>= 0, finite, including ``"unknown"``); they are
            normalised to sum to 1.

    Raises:
        ValueError: a negative or non-finite probability, or all zero.
    """

    def __init__(self, probabilities: Mapping[str, float]) -> None:
        values = np.array([float(v) for v in probabilities.values()])
        if not np.all(np.isfinite(values)) or np.any(values < 0) or values.sum() <= 0:
            raise ValueError(f"probabilities must be finite, >= 0, not all 0: {probabilities}")
        total = float(values.sum())
        self._p = {k: float(v) / total for k, v in probabilities.items()}
        if UNKNOWN not in self._p:
            raise ValueError(f"a posterior has the key {UNKNOWN!r}")

    def __getitem__(self, key: str) -> float:
        return self._p[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._p)

    def __len__(self) -> int:
        return len(self._p)

    @property
    def best(self) -> str:
        """The most probable name (``"unknown"`` included; first in order on ties)."""
        return max(self._p, key=self._p.__getitem__)

    def __repr__(self) -> str:
        inner = ", ".join(f"{k}: {v:.3f}" for k, v in self._p.items())
        return f"Posterior({inner})"


@runtime_checkable
class Recogniser(Protocol):
    """What an assistant needs of a recogniser."""

    @property
    def skills(self) -> tuple[str, ...]:
        """The known skills' names."""
        ...

    def reset(self) -> None:
        """Start a new session."""
        ...

    def update(self, frame: SessionFrame) -> Posterior:
        """Take the next frame (one per control step, from reset on); the posterior now."""
        ...

    def add_skill(self, name: str, sessions: Sequence[Sequence[SessionFrame]]) -> None:
        """Learn ``sessions`` of skill ``name`` on line (new or known skill)."""
        ...


@dataclass(frozen=True, eq=False)
class LibrarySession:
    """One stored session of a skill as the recognisers use it.

    Attributes:
        skill: the skill's name (the class).
        group: who performed it (the person id, or a unique tag): leave-one-out leaves out a
            whole group, so the threshold is calibrated for new persons.
        features: ``(T, 8)`` :func:`feature_matrix` of its frames.
        time_s: ``(T,)`` the frames' times [s].
    """

    skill: str
    group: str
    features: FloatArray
    time_s: FloatArray


def library_session(skill: str, group: str, frames: Sequence[SessionFrame]) -> LibrarySession:
    """A :class:`LibrarySession` from frames."""
    return LibrarySession(
        skill=skill,
        group=group,
        features=feature_matrix(frames),
        time_s=np.array([f.time_s for f in frames], dtype=np.float64),
    )


def load_library(db: SkillDB, task: str = GLOVE_TASK) -> list[LibrarySession]:
    """The glove sessions of ``task`` stored in ``db``, the skill's name as its class.

    Args:
        db: an open skill database.
        task: the env id of the sessions to use.

    Returns:
        One :class:`LibrarySession` per stored session, by id.

    Raises:
        InputError: the database holds no session of ``task``.
    """
    out = []
    for summary in db.list_skills(task=task):
        skill = db.get(summary.id)
        group = skill.person_id or f"skill-{summary.id}"
        out.append(library_session(skill.name, group, frames_from_skill(skill)))
    if not out:
        raise InputError(
            f"{db.path} holds no {task} session; record some with `ias-gym skills record "
            f"--env {task} --policy teleop --skill NAME --person ID --db {db.path}`"
        )
    return out


def unknown_probability(score: float, loo_scores: Sequence[float]) -> float:
    """``p(unknown)`` of a novelty score given the library's leave-one-out scores.

    A logistic in ``log(score)``: 0.5 at the :data:`UNKNOWN_QUANTILE` quantile of the
    leave-one-out scores, :data:`UNKNOWN_AT_MEDIAN` at their median.

    Args:
        score: the session's novelty score (> 0; larger: less like any stored skill).
        loo_scores: the library's leave-one-out scores (>= 1).

    Returns:
        The probability in [0, 1].
    """
    logs = np.log(np.maximum(np.asarray(loo_scores, dtype=np.float64), 1e-12))
    thr = float(np.quantile(logs, UNKNOWN_QUANTILE))
    med = float(np.median(logs))
    # at least a factor 1.1 between median and threshold (a library of near-identical
    # sessions would otherwise make the logistic a step)
    width = max(thr - med, math.log(1.1))
    slope = math.log((1.0 - UNKNOWN_AT_MEDIAN) / UNKNOWN_AT_MEDIAN) / width
    z = slope * (math.log(max(score, 1e-12)) - thr)
    return float(1.0 / (1.0 + math.exp(-min(max(z, -700.0), 700.0))))


_R = TypeVar("_R", bound="LibraryRecogniser")


class LibraryRecogniser:
    """A recogniser on a library of stored sessions (the base of both methods).

    Implements :class:`Recogniser`; subclasses supply the evidence of each skill and the
    novelty score. :meth:`score_session` scores a whole session at once.

    Args:
        sessions: the library (each skill's sessions; several persons per skill).

    Raises:
        InputError: empty library, a skill named ``"unknown"``, or no skill performed by
            two persons (the unknown threshold cannot be calibrated).
    """

    method = ""

    def __init__(self, sessions: Sequence[LibrarySession]) -> None:
        if not sessions:
            raise InputError("a recogniser needs at least one stored session")
        self._classes: dict[str, list[LibrarySession]] = {}
        for s in sessions:
            self._check_name(s.skill)
            self._classes.setdefault(s.skill, []).append(s)
        self._fit_all()
        self._loo: list[float] = []
        self._feats: list[FloatArray] = []
        self._times: list[float] = []
        self._reset_state()
        for s in sessions:
            self._loo.extend(self._loo_score(s))
        if not self._loo:
            raise InputError(
                "the unknown threshold is calibrated by leave-one-person-out: the library "
                "needs at least one skill performed by two persons (or two sessions)"
            )
        self.reset()

    @classmethod
    def from_db(cls: type[_R], db: SkillDB, task: str = GLOVE_TASK) -> _R:
        """The recogniser of the glove sessions in ``db`` (:func:`load_library`)."""
        return cls(load_library(db, task))

    @staticmethod
    def _check_name(name: str) -> None:
        if not isinstance(name, str) or not name.strip() or name == UNKNOWN:
            raise InputError(f"skill name {name!r} is not usable: non-empty and not {UNKNOWN!r}")

    @property
    def skills(self) -> tuple[str, ...]:
        """The known skills' names, in the order they were learnt."""
        return tuple(self._classes)

    @property
    def loo_scores(self) -> tuple[float, ...]:
        """The library's leave-one-person-out novelty scores (the unknown calibration)."""
        return tuple(self._loo)

    def reset(self) -> None:
        """Start a new session (forget the frames seen so far)."""
        self._feats = []
        self._times = []
        self._ref: FloatArray | None = None  # the raw features at FEATURE_T0
        self._reset_state()
        n = len(self._classes)
        self._posterior = Posterior({**dict.fromkeys(self._classes, 1.0 / n), UNKNOWN: 0.0})
        self._novelty = 0.0

    @property
    def posterior(self) -> Posterior:
        """The posterior after the last :meth:`update` (uniform over skills before any)."""
        return self._posterior

    @property
    def novelty(self) -> float:
        """The session's novelty score so far (the score behind ``p(unknown)``)."""
        return self._novelty

    def update(self, frame: SessionFrame) -> Posterior:
        """Take the next frame and return the posterior over skills and ``"unknown"``.

        Args:
            frame: the session's next control step (the first after :meth:`reset` is the
                frame of the env's reset).

        Returns:
            The posterior now.
        """
        raw = features(frame)
        if self._ref is None and frame.time_s >= FEATURE_T0 - 1e-9:
            self._ref = raw
        self._feats.append(np.zeros_like(raw) if self._ref is None else raw - self._ref)
        self._times.append(frame.time_s)
        result = self._evidence()
        if result is not None:
            evidence, self._novelty = result
            self._posterior = self._make_posterior(evidence, self._novelty)
        return self._posterior

    def _make_posterior(self, evidence: Mapping[str, float], novelty: float) -> Posterior:
        names = list(evidence)
        e = np.array([evidence[k] for k in names])
        known = np.exp(e - e.max())
        known /= known.sum()
        p_u = unknown_probability(novelty, self._loo)
        probs = {k: float(p) * (1.0 - p_u) for k, p in zip(names, known, strict=True)}
        probs[UNKNOWN] = p_u
        return Posterior(probs)

    def add_skill(self, name: str, sessions: Sequence[Sequence[SessionFrame]]) -> None:
        """Learn sessions of skill ``name`` on line, without refitting the other skills.

        Args:
            name: the skill's name (new, or known: more sessions of it).
            sessions: its sessions, each the frames from reset on.

        Raises:
            InputError: the name is ``"unknown"`` or empty, or no sessions are given.
        """
        self._check_name(name)
        if not sessions:
            raise InputError(f"add_skill({name!r}) needs at least one session")
        n0 = sum(len(v) for v in self._classes.values())
        new = [library_session(name, f"online-{n0 + i}", s) for i, s in enumerate(sessions)]
        self._classes.setdefault(name, []).extend(new)
        self._fit_class(name)
        for s in new:
            self._loo.extend(self._loo_score(s))
        self.reset()

    def score_session(self, frames: Sequence[SessionFrame]) -> tuple[Posterior, float]:
        """The final posterior and novelty score of a whole session (resets the stream).

        Args:
            frames: the session from reset on.

        Returns:
            The posterior after the last frame and the novelty score.
        """
        self.reset()
        feats = feature_matrix(frames)
        times = np.array([f.time_s for f in frames], dtype=np.float64)
        evidence, novelty = self._batch_evidence(feats, times, self._classes)
        self._posterior = self._make_posterior(evidence, novelty)
        self._novelty = novelty
        return self._posterior, novelty

    def _loo_score(self, s: LibrarySession) -> list[float]:
        """The novelty of ``s`` against the library without its group's sessions of its skill
        (empty if no other group performed it)."""
        rest = [o for o in self._classes[s.skill] if o.group != s.group]
        if not rest:
            return []
        classes = {**self._classes, s.skill: rest}
        return [self._batch_evidence(s.features, s.time_s, classes, refit=s.skill)[1]]

    # subclass hooks
    def _fit_all(self) -> None:
        for name in self._classes:
            self._fit_class(name)

    def _fit_class(self, name: str) -> None:
        raise NotImplementedError

    def _reset_state(self) -> None:
        raise NotImplementedError

    def _evidence(self) -> tuple[dict[str, float], float] | None:
        raise NotImplementedError

    def _batch_evidence(
        self,
        feats: FloatArray,
        times: FloatArray,
        classes: Mapping[str, Sequence[LibrarySession]],
        refit: str | None = None,
    ) -> tuple[dict[str, float], float]:
        raise NotImplementedError


# ---------------------------------------------------------------------------------- DTW
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


# -------------------------------------------------------------------------- phase model
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


#: The recognisers by method name.
METHODS: dict[str, type[LibraryRecogniser]] = {"dtw": DTWRecogniser, "phase": PhaseRecogniser}


def make_recogniser(method: str, db: SkillDB | Sequence[LibrarySession]) -> LibraryRecogniser:
    """A recogniser of the glove sessions in ``db``.

    Args:
        method: ``"dtw"`` (baseline) or ``"phase"`` (the phase-aware probabilistic model).
        db: an open :class:`~ias_gym.skills.SkillDB`, or library sessions.

    Returns:
        The recogniser.

    Raises:
        InputError: unknown method, or a library it cannot be built from.
    """
    if method not in METHODS:
        raise InputError(
            f"method {method!r} is not a recogniser; choose one of {', '.join(METHODS)}"
        )
    sessions = db if isinstance(db, Sequence) else load_library(db)
    return METHODS[method](sessions)


def acquire_skill(
    db: SkillDB,
    recogniser: Recogniser,
    skill: Skill,
    frames: Sequence[SessionFrame],
    name: str,
) -> int:
    """Store a session as skill ``name`` and teach it to the recogniser (on-line acquisition).

    The session is written in one transaction (:meth:`~ias_gym.skills.SkillDB.add`); only
    when that has succeeded does the recogniser learn it, so a failure leaves both as they
    were.

    Args:
        db: the skill database (open for writing).
        recogniser: the recogniser to extend (:meth:`Recogniser.add_skill`).
        skill: the recorded session (:func:`~ias_gym.assist.stream.record_session`).
        frames: its frames.
        name: the new skill's name (not ``"unknown"``).

    Returns:
        The stored skill's id.

    Raises:
        InputError: an unusable name.
    """
    LibraryRecogniser._check_name(name)
    kwargs = dict(skill.env_kwargs)
    kwargs["acquired_as"] = name
    stored = dataclasses.replace(skill, name=name, env_kwargs=kwargs, id=None, created=None)
    skill_id = db.add(stored)
    recogniser.add_skill(name, [frames])
    return skill_id

"""Intent recognition on a partial glove session (paper Flow 3) with unknown detection.

The assistant "identifies and anticipates the action the human operator wants to perform";
a recogniser turns the frames of a running glove session (:class:`SessionFrame`, one per
control step) into a :class:`Posterior` over the skills of a library plus ``"unknown"``,
updated at every step. This module holds that interface (:class:`Recogniser`), the
posterior, the library and its base recogniser (:class:`LibraryRecogniser`), the unknown
detection and on-line acquisition; the features are
:mod:`~ias_gym.assist.recognition_features`'s, the two recognisers
:mod:`~ias_gym.assist.dtw_recogniser`'s and :mod:`~ias_gym.assist.phase_recogniser`'s, and
:func:`~ias_gym.assist.recogniser_registry.make_recogniser` builds one by name:

- :class:`~ias_gym.assist.dtw_recogniser.DTWRecogniser` (``"dtw"``, the baseline):
  1-nearest-neighbour open-end dynamic time warping of the session so far against every
  stored session (dtaidistance's C DTW with the psi relaxation on the template's end, so a
  partial session is matched against the best prefix of a full template). Costs are
  recomputed every :data:`~ias_gym.assist.dtw_recogniser.DTW_STRIDE` steps on the session
  sub-sampled by the same stride (20 Hz); between, the last posterior is kept.
- :class:`~ias_gym.assist.phase_recogniser.PhaseRecogniser` (``"phase"``): a phase-aware
  probabilistic model. Each skill is a mean trajectory and a variance over its phase, learnt
  from its sessions after aligning each to the class mean (delay and speed of the skill's
  own motion); on line, a grid of delay/speed hypotheses per skill accumulates the Gaussian
  log-likelihood of every frame (tempered for the frames' correlation), and the posterior is
  Bayes' rule over the skills with the hypotheses marginalised. The operator may switch from
  one skill to another while performing it (a fixed-share prior over the skills,
  :func:`~ias_gym.assist.phase_recogniser.switching_step`).

Unknown detection (both): a novelty score of the session (DTW: the nearest template's mean
cost per sample; phase: the mean squared Mahalanobis distance per feature along the best
path into the most probable skill and hypothesis) is compared with the library's own
leave-one-person-out scores (every stored session scored against the library without its
person's sessions of that skill):
the threshold is their 95 % quantile, where ``p(unknown) = 0.5``, and ``p(unknown)`` is 0.01
at their median (a logistic in the log score). No number is tuned per skill.

On-line acquisition: :meth:`Recogniser.add_skill` adds the sessions of a new (or known)
skill: DTW stores them as templates, the phase model fits that one skill's mean and
variance; the other skills and the scores already computed stay as they are, only the new
sessions' leave-one-out scores join the pool. :func:`acquire_skill` stores the session in
the :class:`~ias_gym.skills.SkillDB` (one transaction) before the recogniser learns it;
:func:`learn_demonstration` is acquisition mode's rule: a demonstration the recogniser
calls unknown, or the skill being acquired, is stored as that skill.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, TypeVar, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from ias_gym.assist.recognition_features import FEATURE_T0, feature_matrix, features
from ias_gym.assist.stream import SessionFrame, frames_from_skill
from ias_gym.errors import InputError

if TYPE_CHECKING:
    from ias_gym.skills import Skill, SkillDB

FloatArray = NDArray[np.float64]

#: The posterior's key for "none of the stored skills".
UNKNOWN = "unknown"
#: The env whose sessions a library holds.
GLOVE_TASK = "IAS-GloveGrasp-v0"
#: Leave-one-out quantile where p(unknown) = 0.5; p(unknown) = 0.01 at the median.
UNKNOWN_QUANTILE = 0.95
UNKNOWN_AT_MEDIAN = 0.01


def check_skill_name(name: object, what: str = "skill name") -> str:
    """``name`` if a library can store a skill under it (non-empty, not ``"unknown"``).

    Raises:
        InputError: an unusable name.
    """
    if not isinstance(name, str) or not name.strip() or name == UNKNOWN:
        raise InputError(f"{what} {name!r} is not usable: non-empty and not {UNKNOWN!r}")
    return name


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
        features: ``(T, 8)`` :func:`~ias_gym.assist.recognition_features.feature_matrix` of
            its frames.
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
    """The successful glove sessions of ``task`` stored in ``db``, the skill's name as its
    class. A failed session (its ``is_success`` false: the pen dropped, the skill's motion
    not done) is no demonstration of its skill, and it is left out: a model that learnt
    a dropped pen as a tilt would take other sessions for it.

    Args:
        db: an open skill database.
        task: the env id of the sessions to use.

    Returns:
        One :class:`LibrarySession` per stored successful session, by id.

    Raises:
        InputError: the database holds no successful session of ``task``.
    """
    out = []
    for summary in db.list_skills(task=task, success=True):
        skill = db.get(summary.id)
        group = skill.person_id or f"skill-{summary.id}"
        out.append(library_session(skill.name, group, frames_from_skill(skill)))
    if not out:
        raise InputError(
            f"{db.path} holds no successful {task} session; record some with `ias-gym skills "
            f"record --env {task} --policy teleop --skill NAME --person ID --db {db.path}`"
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
        check_skill_name(name)

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


@dataclass(frozen=True)
class Acquisition:
    """What acquisition mode did with one demonstration (:func:`learn_demonstration`).

    Attributes:
        recognised: the recogniser's answer on the whole session before it learnt anything.
        stored_as: the skill it was stored as, or None (taken for another known skill).
        skill_id: its id in the database, or None.
    """

    recognised: str
    stored_as: str | None
    skill_id: int | None


def learn_demonstration(
    db: SkillDB,
    recogniser: Recogniser,
    skill: Skill,
    frames: Sequence[SessionFrame],
    name: str,
) -> Acquisition:
    """Acquisition mode (paper Flow 3: "in case of unknown tasks, the assistant automatically
    switches in acquisition mode") for one demonstration of the skill ``name``.

    The session is stored as ``name`` (:func:`acquire_skill`) when the recogniser calls it
    ``unknown`` (the first demonstration of a new skill, or one the few stored sessions do
    not yet cover) or recognises it as ``name`` already; a session taken for another known
    skill is not stored, so a known skill is never acquired twice under two names.

    Raises:
        InputError: an unusable name.
    """
    check_skill_name(name)
    recogniser.reset()
    post = Posterior({UNKNOWN: 1.0})
    for frame in frames:
        post = recogniser.update(frame)
    recogniser.reset()
    best = post.best
    if best not in (UNKNOWN, name):
        return Acquisition(best, None, None)
    return Acquisition(best, name, acquire_skill(db, recogniser, skill, frames, name))

"""How well a recogniser knows the intent: accuracy over the skill's motion, triggers, unknowns.

Every measure counts a session from where the skill's own motion starts, as the session's
record says (:func:`truth_window`: its stored phases): the reach-pinch-lift before it is the
same for every skill. The *observed fraction* f of a session is the time
``t_start + f (t_end - t_start)``; ``lift_hold`` has no motion, so its window is the hold
until the session's end.

- ``accuracy[f]``: the share of sessions whose posterior's most probable name (``"unknown"``
  included) at fraction f is the true skill; ``recog_acc_at_33`` and ``recog_acc_at_60``;
- ``time_to_recognise_s``: the mean time [s] after the motion's start at which the true
  skill's posterior passes 0.9 and stays above it to the end (sessions that never get there
  are counted in ``recognised_fraction`` instead);
- ``false_trigger_rate``: the share of sessions in which a wrong skill's posterior passes
  0.9 at any time;
- ``unknown_auroc`` (:func:`unknown_auroc`): each skill in turn is left out of the library
  and its sessions are scored as unknown against the sessions of the known skills, by their
  final novelty score; the area under the ROC curve of all folds pooled.

How a recogniser follows an operator who changes their mind is
:mod:`~ias_gym.assist.intent_switches`'s.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ias_gym.assist.recogniser_registry import make_recogniser
from ias_gym.assist.recognition import (
    UNKNOWN,
    LibrarySession,
    Recogniser,
    library_session,
)
from ias_gym.assist.stream import SessionFrame, frames_from_skill
from ias_gym.errors import InputError
from ias_gym.glove.skills import SKILLS, check_skill
from ias_gym.rates import Rate
from ias_gym.skills.glove_session import PHASE_INFO
from ias_gym.skills.glove_session import motion_window as glove_motion_window

if TYPE_CHECKING:
    from ias_gym.skills import Skill, SkillDB

#: The observed fractions of the accuracy curve.
FRACTIONS: tuple[float, ...] = tuple(round(0.1 * i, 1) for i in range(1, 11))
#: A posterior "triggers" above this.
TRIGGER = 0.9


@dataclass(frozen=True, eq=False)
class LabelledSession:
    """A glove session with its truth.

    Attributes:
        skill: the skill performed.
        person_id: who performed it.
        frames: its frames from reset on.
        t_start: where the skill's own motion starts [s].
        t_end: where it ends [s] (:func:`truth_window`).
    """

    skill: str
    person_id: str
    frames: list[SessionFrame]
    t_start: float
    t_end: float

    def library(self) -> LibrarySession:
        """As a library session (the person as its group)."""
        return library_session(self.skill, self.person_id, self.frames)


def truth_window(skill: Skill) -> tuple[float, float]:
    """``(t_start, t_end)`` [s] of a stored glove session's own motion, from its record
    (:func:`~ias_gym.skills.glove_session.motion_window`); a skill without motion
    (``lift_hold``) holds to the session's end.

    Raises:
        InputError: the record has no phases (recorded before sessions stored them).
    """
    window = glove_motion_window(skill)
    if window is None:
        raise InputError(
            f"skill {skill.id} ({skill.name!r}) does not store its phases (info "
            f"{PHASE_INFO!r}); record it anew with `ias-gym skills record`"
        )
    start, end = window
    return start, end if end > start else float(skill.model.time[-1])


def labelled_session(skill: Skill) -> LabelledSession:
    """A stored glove skill with its truth (``env_kwargs`` ``skill`` and the person).

    Raises:
        InputError: the skill names no glove skill or person.
    """
    name = skill.env_kwargs.get("skill", skill.name)
    person = skill.person_id
    if name not in SKILLS or person is None:
        raise InputError(
            f"skill {skill.id} ({skill.name!r}) is not a labelled glove session: it needs "
            f"env_kwargs skill in {SKILLS} and a person id"
        )
    start, end = truth_window(skill)
    return LabelledSession(str(name), person, frames_from_skill(skill), start, end)


def record_sessions(
    persons: Sequence[str],
    skills: Sequence[str],
    episodes: int,
    seed: int = 0,
    db: SkillDB | None = None,
    progress: Callable[[Iterable[Any]], Iterable[Any]] | None = None,
) -> list[LabelledSession]:
    """Record teleoperated glove sessions of every person x skill (``episodes`` each).

    Args:
        persons: person ids.
        skills: skill names (:data:`~ias_gym.glove.skills.SKILLS`).
        episodes: sessions per person and skill (>= 1); episode i is reset with
            ``seed + i``.
        seed: the first reset seed.
        db: where to store them too (one transaction each), or ``None``.
        progress: wraps the list of (person, skill, episode) jobs (e.g. ``tqdm``).

    Returns:
        The sessions in job order.

    Raises:
        InputError: an unknown skill, an invalid person id or ``episodes`` < 1.
    """
    import gymnasium as gym

    import ias_gym  # noqa: F401 - registers the envs
    from ias_gym.assist.stream import record_session

    if episodes < 1:
        raise InputError(f"episodes must be >= 1, got {episodes}")
    for s in skills:
        check_skill(s)
    jobs = [(p, s, i) for p in persons for s in skills for i in range(episodes)]
    out = []
    for person, skill, i in progress(jobs) if progress else jobs:
        env = gym.make("IAS-GloveGrasp-v0", person_id=person, skill=skill)
        try:
            stored, frames = record_session(env, seed=seed + i)
        finally:
            env.close()
        if db is not None:
            db.add(stored)
        start, end = truth_window(stored)
        out.append(LabelledSession(skill, person, frames, start, end))
    return out


def posterior_trace(
    recogniser: Recogniser, frames: Sequence[SessionFrame]
) -> tuple[NDArray[np.float64], list[str], NDArray[np.float64]]:
    """Run a session through a recogniser, one update per frame.

    Returns:
        ``(P, names, times)``: ``P[t, j]`` the posterior of ``names[j]`` after frame t
        (``names``: the recogniser's skills, then ``"unknown"``), and the frames' times [s].
    """
    recogniser.reset()
    names = [*recogniser.skills, UNKNOWN]
    rows = []
    for f in frames:
        post = recogniser.update(f)
        rows.append([post[n] for n in names])
    times = np.array([f.time_s for f in frames])
    return np.array(rows), names, times


@dataclass(frozen=True)
class SessionResult:
    """What one session's posterior trace says (see the module docstring).

    Attributes:
        skill, person_id: the truth.
        correct_at: per :data:`FRACTIONS`, whether the most probable name is the skill.
        time_to_recognise_s: [s] after the motion's start, ``None``: never recognised.
        false_trigger: a wrong skill's posterior passed :data:`TRIGGER`.
        final: the most probable name after the last frame.
    """

    skill: str
    person_id: str
    correct_at: tuple[bool, ...]
    time_to_recognise_s: float | None
    false_trigger: bool
    final: str


def score_trace(
    P: NDArray[np.float64],
    names: Sequence[str],
    times: NDArray[np.float64],
    session: LabelledSession,
    truth: str | None = None,
) -> SessionResult:
    """Score a posterior trace against the session's truth.

    Args:
        P, names, times: :func:`posterior_trace`'s output.
        session: the session.
        truth: the name the recogniser should give (default: the session's skill; e.g. the
            name it was acquired under).

    Returns:
        The session's result.
    """
    truth = session.skill if truth is None else truth
    j = names.index(truth) if truth in names else -1
    correct = []
    for f in FRACTIONS:
        t = session.t_start + f * (session.t_end - session.t_start)
        i = min(int(np.searchsorted(times, t - 1e-9)), len(times) - 1)
        correct.append(bool(names[int(np.argmax(P[i]))] == truth))
    ttr: float | None = None
    if j >= 0:
        above = P[:, j] > TRIGGER
        if above[-1]:
            below = np.flatnonzero(~above)
            first = int(below[-1]) + 1 if len(below) else 0
            ttr = float(times[first] - session.t_start)
    wrong = [k for k, n in enumerate(names) if n not in (truth, UNKNOWN)]
    false_trigger = bool(np.any(P[:, wrong] > TRIGGER)) if wrong else False
    return SessionResult(
        skill=session.skill,
        person_id=session.person_id,
        correct_at=tuple(correct),
        time_to_recognise_s=ttr,
        false_trigger=false_trigger,
        final=names[int(np.argmax(P[-1]))],
    )


def summarise(results: Sequence[SessionResult]) -> dict[str, Any]:
    """The recognition keys of a set of session results.

    Returns:
        ``sessions``, ``accuracy_by_fraction`` (fraction -> accuracy), ``recog_acc_at_33``,
        ``recog_acc_at_60``, ``time_to_recognise_s`` (mean over recognised sessions, or
        ``None``), ``recognised_fraction``, ``false_trigger_rate``, ``final_accuracy``, and
        ``rates``: the per-session proportions (correct at 60 % of the motion, correct at the
        end, a false trigger) with their 95 % Wilson intervals
        (:meth:`~ias_gym.rates.Rate.to_dict`).

    Raises:
        InputError: no results.
    """
    if not results:
        raise InputError("no sessions to summarise")
    acc = np.mean([r.correct_at for r in results], axis=0)
    curve = {f"{f:.1f}": float(a) for f, a in zip(FRACTIONS, acc, strict=True)}
    ttr = [r.time_to_recognise_s for r in results if r.time_to_recognise_s is not None]
    at60 = FRACTIONS.index(0.6)
    rates = {
        "recog_acc_at_60": Rate.of([r.correct_at[at60] for r in results]),
        "final_accuracy": Rate.of([r.final == r.skill for r in results]),
        "false_trigger_rate": Rate.of([r.false_trigger for r in results]),
    }
    return {
        "sessions": len(results),
        "accuracy_by_fraction": curve,
        "recog_acc_at_33": _interp_acc(acc, 0.33),
        "recog_acc_at_60": rates["recog_acc_at_60"].value,
        "time_to_recognise_s": float(np.mean(ttr)) if ttr else None,
        "recognised_fraction": len(ttr) / len(results),
        "false_trigger_rate": rates["false_trigger_rate"].value,
        "final_accuracy": rates["final_accuracy"].value,
        "rates": {key: rate.to_dict() for key, rate in rates.items()},
    }


def _interp_acc(acc: NDArray[np.float64], fraction: float) -> float:
    return float(np.interp(fraction, FRACTIONS, acc))


def evaluate_recogniser(
    recogniser: Recogniser,
    sessions: Sequence[LabelledSession],
    progress: Callable[[Iterable[Any]], Iterable[Any]] | None = None,
) -> tuple[dict[str, Any], list[SessionResult]]:
    """Run every session through ``recogniser`` step by step and score it.

    Args:
        recogniser: the recogniser (its library must not hold these sessions' persons).
        sessions: labelled sessions.
        progress: wraps the sessions (e.g. ``tqdm``).

    Returns:
        :func:`summarise`'s keys and the per-session results.
    """
    results = []
    for s in progress(sessions) if progress else sessions:
        P, names, times = posterior_trace(recogniser, s.frames)
        results.append(score_trace(P, names, times, s))
    return summarise(results), results


def auroc(positive: Sequence[float], negative: Sequence[float]) -> float:
    """Area under the ROC curve of scores (positives should score higher): the
    Mann-Whitney statistic, ties counted half (sklearn is not a dependency).

    Raises:
        InputError: either set is empty.
    """
    pos, neg = np.asarray(positive, dtype=float), np.asarray(negative, dtype=float)
    if len(pos) == 0 or len(neg) == 0:
        raise InputError("AUROC needs positive and negative scores")
    greater = (pos[:, None] > neg[None, :]).sum()
    ties = (pos[:, None] == neg[None, :]).sum()
    return float((greater + 0.5 * ties) / (len(pos) * len(neg)))


def unknown_auroc(
    method: str,
    library: Sequence[LibrarySession],
    sessions: Sequence[LabelledSession],
) -> dict[str, Any]:
    """Leave each skill out of the library in turn; score the sessions as unknown.

    Args:
        method: the recogniser (:func:`~ias_gym.assist.recogniser_registry.make_recogniser`).
        library: the library's sessions.
        sessions: test sessions (other persons).

    Returns:
        ``unknown_auroc`` (all folds pooled), ``unknown_detected_rate`` (left-out sessions
        whose final most probable name is ``"unknown"``), ``known_as_unknown_rate`` (known
        sessions that end as unknown) and ``unknown_auroc_by_skill``.
    """
    pos: list[float] = []
    neg: list[float] = []
    detected, rejected = [], []
    by_skill = {}
    for left_out in sorted({s.skill for s in library}):
        rec = make_recogniser(method, [s for s in library if s.skill != left_out])
        p_fold, n_fold = [], []
        for s in sessions:
            post, novelty = rec.score_session(s.frames)
            if s.skill == left_out:
                p_fold.append(novelty)
                detected.append(post.best == UNKNOWN)
            else:
                n_fold.append(novelty)
                rejected.append(post.best == UNKNOWN)
        pos += p_fold
        neg += n_fold
        if p_fold and n_fold:
            by_skill[left_out] = auroc(p_fold, n_fold)
    return {
        "unknown_auroc": auroc(pos, neg),
        "unknown_detected_rate": float(np.mean(detected)) if detected else None,
        "known_as_unknown_rate": float(np.mean(rejected)) if rejected else None,
        "unknown_auroc_by_skill": by_skill,
    }


def check_held_out(library: Sequence[LibrarySession], persons: Sequence[str]) -> None:
    """Refuse test persons whose sessions are in the library.

    Raises:
        InputError: a person of ``persons`` performed a library session.
    """
    seen = sorted({s.group for s in library} & set(persons))
    if seen:
        raise InputError(
            f"persons {', '.join(seen)} have sessions in the library; evaluate on persons "
            "the library has not seen"
        )


def evaluate_methods(
    library: Sequence[LibrarySession],
    sessions: Sequence[LabelledSession],
    methods: Sequence[str],
    progress: Callable[[Iterable[Any]], Iterable[Any]] | None = None,
) -> dict[str, dict[str, Any]]:
    """Evaluate recognisers built on ``library`` on held-out ``sessions``.

    Args:
        library: the library's sessions.
        sessions: labelled sessions of persons not in the library.
        methods: recogniser names (``"dtw"``, ``"phase"``).
        progress: wraps each method's sessions (e.g. ``tqdm``).

    Returns:
        Per method, :func:`summarise`'s keys and :func:`unknown_auroc`'s.

    Raises:
        InputError: a test person is in the library, or an unknown method.
    """
    check_held_out(library, sorted({s.person_id for s in sessions}))
    out = {}
    for method in methods:
        rec = make_recogniser(method, library)
        summary, _ = evaluate_recogniser(rec, sessions, progress)
        out[method] = {"method": method, **summary, **unknown_auroc(method, library, sessions)}
    return out

"""Judging an assistant over a population: success with and without it per impairment
(:func:`evaluate_assistance`, :class:`ImpairmentScore`), the unimpaired reference session a
session is judged against (:func:`reference_session`), and intent-switch latencies
(:func:`switch_latency`).

The sessions themselves, the success test, the intervention and the latency of one session
are :mod:`ias_gym.assist.sessions`'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from ias_gym.assist.sessions import SessionResult, run_session, session_record, session_success
from ias_gym.glove.impairments import reference_kwargs

#: A reference counts only if the unimpaired session from this many nearby starts
#: (:func:`ias_gym.perturbed_starts.perturbed_starts`: ``qpos`` 1e-9 away, another machine's last
#: bits) also holds the pen throughout and stays within the tolerances of it
#: (:func:`reference_session`).
REFERENCE_STARTS = 2


@dataclass
class ImpairmentScore:
    """Success with and without the assistant for one impairment.

    Attributes:
        successes_unassisted: sessions that succeed without the assistant.
        successes_assisted: with it.
        intervention: the assistant's mean intervention [-] (:mod:`ias_gym.assist.sessions`).
        sessions: number of sessions of each kind that count.
        excluded: sessions left out for want of a reference (:func:`reference_session`): the
            unimpaired person's own session failed, lost a pad on the way, or did either
            from a start 1e-9 away.
        records: one :func:`~ias_gym.assist.sessions.session_record` per session, excluded
            ones included (not part of :meth:`to_json`: a table's per-session file).
    """

    successes_unassisted: int
    successes_assisted: int
    intervention: float
    sessions: int
    excluded: int = 0
    records: list[dict[str, Any]] = field(default_factory=list)

    @property
    def success_unassisted(self) -> float:
        """Share of the sessions that succeed without the assistant (NaN: no session) [-]."""
        return self.successes_unassisted / self.sessions if self.sessions else math.nan

    @property
    def success_assisted(self) -> float:
        """Share of the sessions that succeed with it (NaN: no session) [-]."""
        return self.successes_assisted / self.sessions if self.sessions else math.nan

    @classmethod
    def merge(cls, parts: list[ImpairmentScore]) -> ImpairmentScore:
        """One score of several (e.g. one per person, computed apart): counts and records
        added in order, the intervention averaged over all their sessions."""
        weighted = [(p.intervention, p.sessions) for p in parts if p.sessions]
        sessions = sum(p.sessions for p in parts)
        return cls(
            sum(p.successes_unassisted for p in parts),
            sum(p.successes_assisted for p in parts),
            sum(x * n for x, n in weighted) / sessions if sessions else math.nan,
            sessions,
            sum(p.excluded for p in parts),
            [r for p in parts for r in p.records],
        )

    def to_json(self) -> dict[str, Any]:
        """The three shares as a JSON object (``sessions`` and ``excluded`` as well; null
        for a share of no session), and the two successes as
        :meth:`~ias_gym.rates.Rate.to_dict` with their 95 % intervals (``unassisted``,
        ``assisted``; null without sessions)."""
        from ias_gym.rates import Rate

        def number(x: float) -> float | None:
            return None if math.isnan(x) else x

        return {
            "success_unassisted": number(self.success_unassisted),
            "success_assisted": number(self.success_assisted),
            "intervention": number(self.intervention),
            "sessions": self.sessions,
            "excluded": self.excluded,
            **{
                name: Rate(successes, self.sessions).to_dict() if self.sessions else None
                for name, successes in (
                    ("unassisted", self.successes_unassisted),
                    ("assisted", self.successes_assisted),
                )
            },
        }


def reference_session(
    person: str, skill: str, seed: int, **env_kwargs: Any
) -> SessionResult | None:
    """The unimpaired, unassisted session of ``person`` performing ``skill`` from reset
    ``seed``: what an assisted session is judged against; None if it is no reference.
    ``env_kwargs`` go to the env (e.g. ``hand_scale``: the same person with another hand).

    It is none if it fails itself
    (:meth:`~ias_gym.assist.sessions.SessionResult.held_throughout`: the env's success at
    the end, and both pads on the pen at every step from the lift on; a re-grasp makes the
    intended motion chaotic), or if it is a knife edge: from
    :data:`REFERENCE_STARTS` starts 1e-9 away the same person drops the pen, re-grasps, or
    moves it out of the tolerances. Such a person loses the pen on another machine without
    any assistant, so neither a success nor a loss with one means anything there (measured:
    docs/assistance.md).
    """
    from ias_gym.perturbed_starts import perturbed_starts

    env = gym.make("IAS-GloveAssist-v0", person_id=person, skill=skill, **env_kwargs)
    try:
        starts = list(perturbed_starts(env, seed, REFERENCE_STARTS))
        ref = run_session(env, None, seed, starts[0])  # the seed's own start (None)
        if not ref.held_throughout():
            return None
        for options in starts[1:]:
            nearby = run_session(env, None, seed, options)
            if not (nearby.held_throughout() and session_success(nearby, ref)):
                return None
        return ref
    finally:
        env.close()


def evaluate_assistance(
    make_assistant: Any,
    persons: list[str],
    impairments: list[str],
    episodes: int,
    seed: int,
    skills: tuple[str, ...] | None = None,
    progress: Any = None,
    env_kwargs: dict[str, Any] | None = None,
    operator: str = "closed_loop",
) -> dict[str, ImpairmentScore]:
    """Success with and without an assistant per impairment (:mod:`ias_gym.assist.sessions`).

    For every person and impairment, ``episodes`` sessions: session ``i`` performs skill
    ``skills[i % len(skills)]`` from reset seed ``seed + i``, once without and once with
    the assistant, each judged against the unimpaired session of the same person, skill and
    seed (run once and reused). A session without a reference (:func:`reference_session`:
    the unimpaired session fails itself, re-grasps, or does either from a start 1e-9 away)
    is left out and counted in ``excluded``.

    Args:
        make_assistant: ``() -> Assistant``, a fresh assistant.
        persons: person ids.
        impairments: impairment specs (:mod:`~ias_gym.glove.impairment_spec`).
        episodes: sessions per person and impairment.
        seed: the first reset seed.
        skills: the skills to cycle through (default all six glove skills).
        progress: called with no argument after every session pair (e.g. a bar's update).
        env_kwargs: further ``gym.make`` kwargs of the impaired sessions (e.g. ``strength``).
        operator: the simulated person, of every session and reference: ``"closed_loop"``
            or the open ``"script"``.

    Returns:
        ``{impairment: ImpairmentScore}``.
    """
    from ias_gym.glove.skills import SKILLS

    skills = skills or SKILLS
    extra = {**(env_kwargs or {}), "operator": operator}
    references: dict[tuple[str, str, int, str], SessionResult | None] = {}
    out = {}
    for imp in impairments:
        ok_u, ok_a, interv = [], [], []
        records: list[dict[str, Any]] = []
        excluded = 0
        for person in persons:
            for i in range(episodes):
                skill, s = skills[i % len(skills)], seed + i
                env = gym.make(
                    "IAS-GloveAssist-v0", person_id=person, skill=skill, impairment=imp, **extra
                )
                drawn = env.unwrapped.impairment  # type: ignore[attr-defined]
                same = reference_kwargs(drawn)  # ``sampled``: the drawn family's
                key = (person, skill, s, repr(same))
                if key not in references:
                    references[key] = reference_session(person, skill, s, **same, operator=operator)
                ref = references[key]
                record: dict[str, Any] = {
                    "person": person,
                    "skill": skill,
                    "seed": s,
                    "impairment": drawn.spec,
                }
                if ref is None:
                    env.close()
                    excluded += 1
                    records.append({**record, "excluded": True})
                    if progress is not None:
                        progress()
                    continue
                unassisted = run_session(env, None, s)
                assisted = run_session(env, make_assistant(), s)
                env.close()
                record["unassisted"] = session_record(unassisted, ref)
                record["assisted"] = session_record(assisted, ref)
                records.append({**record, "excluded": False})
                ok_u.append(unassisted.success)
                ok_a.append(assisted.success)
                interv.append(assisted.intervention)
                if progress is not None:
                    progress()
        out[imp] = ImpairmentScore(
            sum(ok_u),
            sum(ok_a),
            float(np.mean(interv)) if interv else math.nan,
            len(ok_u),
            excluded,
            records,
        )
    return out


def switch_latency(
    make_assistant: Any,
    persons: list[str],
    pairs: list[tuple[str, str]],
    switch_time: float,
    seed: int,
    operator: str = "closed_loop",
) -> list[float]:
    """Intent-switch latencies [s] (:mod:`ias_gym.assist.sessions`) of an assistant, one per
    person and (from, to) skill pair, with the unimpaired ``operator`` switching at
    ``switch_time`` [s]."""
    out = []
    for person in persons:
        for a, b in pairs:
            env = gym.make(
                "IAS-GloveAssist-v0",
                person_id=person,
                skill=a,
                switch_to=b,
                switch_time=switch_time,
                operator=operator,
            )
            out.append(run_session(env, make_assistant(), seed).switch_latency_s)
            env.close()
    return out

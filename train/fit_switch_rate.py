"""Fit the phase recogniser's switch rate and temper on development persons, by what they
are for.

The phase recogniser (:class:`~ias_gym.assist.phase_recogniser.PhaseRecogniser`) lets the
operator switch from one skill to another between two frames with a probability, its switch
rate. A low rate keeps the first skill's evidence after the operator has changed their mind,
and the session then ends as ``unknown`` (no skill explains all of it); a high one lets a few
odd frames of one skill's session look like another skill, and a skill nobody stored like
pieces of stored ones. Its temper is the share of a frame that counts as an independent
observation: a high one makes the posterior sure early, and sure of the wrong skill in a
session's first ambiguous frames; a low one makes it slow. The two act together: a switch
costs ``2 / temper x log((1 - rate)(K - 1) / rate)`` in the novelty's units
(:func:`~ias_gym.assist.phase_recogniser.switch_cost`), so the grid is spanned by the temper
and that cost, and each point's rate follows from them (for the library's K skills). Every
point is judged on three kinds of session together, every one counted alike:

- **plain**: each person performs every skill once, unimpaired; right when the recogniser
  names the skill at 60 % of its motion and at the end, and never triggers on another
  (:func:`~ias_gym.assist.metrics.score_trace`);
- **switch**: each person performs ``--switches`` pairs of skills (drawn from every ordered
  pair, per person), switching from the first to the second at a time drawn in
  :data:`SWITCH_TIMES` (``IAS-GloveAssist-v0``'s ``switch_to``); right when the recogniser
  names the second from some time after the switch to the end;
- **left out**: each plain session again, against the library without its skill; right when
  it ends as ``unknown``.

Every session is the person in the loop alone (no assistant), recorded as the recognition
table records them (:func:`~ias_gym.assist.metrics.record_sessions`,
:func:`~ias_gym.assist.intent_switches.record_switch_sessions`). Persons are drawn from the
population with ``--seed`` (development persons); the library is ``--db``'s (other
persons). Folds are groups of persons, each fold's point
chosen on the others and its sessions reported with 95 % intervals. The point chosen on all
persons gives the report's ``switch_rate`` and ``temper``; ``PHASE_SWITCH_RATE`` and
``PHASE_TEMPER`` in ``ias_gym/assist/phase_recogniser.py`` hold them (a test compares).

    ias-gym assist library --db out/library.db --population 8 --population-seed 61
    python train/fit_switch_rate.py --db out/library.db --persons 16 --seed 7001 \
        --report out/switch_rate_fit.json
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path

from ias_gym.assist.intent_switches import SwitchSession, evaluate_switches, record_switch_sessions
from ias_gym.assist.metrics import (
    FRACTIONS,
    LabelledSession,
    posterior_trace,
    record_sessions,
    score_trace,
)
from ias_gym.assist.phase_recogniser import PhaseRecogniser, rate_of_cost, switch_cost
from ias_gym.assist.recognition import UNKNOWN, LibrarySession, load_library
from ias_gym.errors import InputError
from ias_gym.glove.impairments import session_rng
from ias_gym.glove.population import population_ids
from ias_gym.glove.skills import SKILLS
from ias_gym.outputs import atomic_output, check_output_files
from ias_gym.rates import rate_json
from ias_gym.runtime.jobs import Backend, run_jobs
from ias_gym.skills import SkillDB

#: The tempers searched: from one independent observation in 10 frames (0.1 s) to one in 40.
TEMPERS = (0.025, 0.035, 0.05, 0.1)
#: The switch costs searched [summed squared z]: at a temper of 0.1 and 6 skills, the rates
#: 1e-12, 1e-20 and 1e-30; 950 is as much as 12 frames at 10 squared z in every feature.
COSTS = (590.0, 950.0, 1410.0)
#: The range a switch time is drawn from [s]: from where the slowest-starting person's
#: motion has begun (the lift ends at 1.7 s, a motion starts up to 0.2 s later) to 1.2 s
#: before the session's end, so the second skill has time to show.
SWITCH_TIMES = (2.0, 2.8)


def drawn_switches(person: str, count: int) -> list[tuple[str, str, float]]:
    """``count`` distinct ordered skill pairs and switch times of ``person``, drawn
    reproducibly per person."""
    rng = session_rng("fit-switch", person, "pairs")
    pairs = [(a, b) for a in SKILLS for b in SKILLS if a != b]
    picked = rng.choice(len(pairs), size=min(count, len(pairs)), replace=False)
    lo, hi = SWITCH_TIMES
    return [(*pairs[int(i)], round(float(rng.uniform(lo, hi)), 2)) for i in picked]


@dataclass(frozen=True)
class RecordJob:
    """A picklable job: one person's plain and switch sessions."""

    switches: int

    def __call__(self, person: str) -> tuple[list[LabelledSession], list[SwitchSession]]:
        plain = record_sessions([person], SKILLS, 1)
        jobs = [(person, a, b, t) for a, b, t in drawn_switches(person, self.switches)]
        return plain, record_switch_sessions(jobs)


@dataclass(frozen=True)
class ScoreJob:
    """A picklable job: every session judged at one rate. Rows ``(kind, person, right)``."""

    library: tuple[LibrarySession, ...]
    plain: tuple[LabelledSession, ...]
    switched: tuple[SwitchSession, ...]

    def __call__(self, point: tuple[float, float]) -> list[tuple[str, str, bool]]:
        temper, rate = point
        rows: list[tuple[str, str, bool]] = []
        rec = PhaseRecogniser(self.library, rate, temper)
        at60 = FRACTIONS.index(0.6)
        for s in self.plain:
            r = score_trace(*posterior_trace(rec, s.frames), s)
            ok = r.correct_at[at60] and r.final == s.skill and not r.false_trigger
            rows.append(("plain", s.person_id, bool(ok)))
        latencies = evaluate_switches(rec, self.switched)["switch_latencies_s"]
        for w, latency in zip(self.switched, latencies, strict=True):
            rows.append(("switch", w.person_id, latency is not None))
        for skill in sorted({s.skill for s in self.library}):
            without = PhaseRecogniser([s for s in self.library if s.skill != skill], rate, temper)
            for s in self.plain:
                if s.skill == skill:
                    post, _ = without.score_session(s.frames)
                    rows.append(("left out", s.person_id, post.best == UNKNOWN))
        return rows


KINDS = ("plain", "switch", "left out")


Point = tuple[float, float]


def choose(outcomes: dict[Point, list[tuple[str, str, bool]]], persons: set[str]) -> Point:
    """The (temper, rate) with the most sessions right among ``persons`` (ties: the lowest
    temper, then the lowest rate: the posterior least sure, the switch least likely)."""
    return max(
        outcomes,
        key=lambda tr: (sum(ok for _, p, ok in outcomes[tr] if p in persons), -tr[0], -tr[1]),
    )


def parse_grid(text: str, name: str, low: float, high: float) -> tuple[float, ...]:
    """Comma-separated numbers in (low, high]; InputError naming ``name`` otherwise."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if not values or not all(low < v <= high for v in values):
        raise InputError(f"{name} {text} must be comma-separated numbers in ({low:g}, {high:g}]")
    return values


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--db", required=True, help="skill library of other development persons")
    ap.add_argument("--persons", type=int, default=16, help="development persons")
    ap.add_argument("--seed", type=int, required=True, help="their population seed")
    ap.add_argument("--switches", type=int, default=6, help="switch sessions per person")
    ap.add_argument("--folds", type=int, default=4, help="cross-validation groups of persons")
    ap.add_argument("--tempers", default=",".join(f"{t:g}" for t in TEMPERS), help="tempers")
    ap.add_argument(
        "--costs", default=",".join(f"{c:g}" for c in COSTS), help="switch costs [squared z]"
    )
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes")
    ap.add_argument("--report", required=True, help="JSON report written")
    ap.add_argument("--overwrite", action="store_true", help="replace --report")
    args = ap.parse_args(argv)
    try:
        tempers = parse_grid(args.tempers, "--tempers", 0.0, 1.0)
        costs = parse_grid(args.costs, "--costs", 0.0, math.inf)
        if not Path(args.db).is_file():
            raise InputError(f"--db {args.db} does not exist (build one: ias-gym assist library)")
        if args.persons < args.folds or args.folds < 2:
            raise InputError(f"--persons {args.persons} cannot fill {args.folds} folds (>= 2)")
        if args.switches < 1:
            raise InputError(f"--switches {args.switches} must be >= 1")
        check_output_files({"--report": args.report}, overwrite=args.overwrite)
        with SkillDB(args.db, readonly=True) as db:
            library = tuple(load_library(db))
    except InputError as exc:
        print(str(exc), file=sys.stderr)
        return 2
    persons = population_ids(args.persons, args.seed)
    backend = Backend.from_options(args.workers)
    recorded = run_jobs(RecordJob(args.switches), persons, backend, desc="persons", progress=True)
    plain = tuple(s for p, _ in recorded for s in p)
    switched = tuple(s for _, w in recorded for s in w)
    skills = len({s.skill for s in library})
    grid = [(t, rate_of_cost(c, skills, t)) for t in tempers for c in costs]
    job = ScoreJob(library, plain, switched)
    scored = run_jobs(job, grid, backend, desc="tempers x costs", progress=True)
    outcomes = dict(zip(grid, scored, strict=True))
    folds = {p: i % args.folds for i, p in enumerate(persons)}
    held: dict[str, list[bool]] = {k: [] for k in KINDS}
    for fold in range(args.folds):
        point = choose(outcomes, {p for p, f in folds.items() if f != fold})
        for kind, person, ok in outcomes[point]:
            if folds[person] == fold:
                held[kind].append(ok)
    temper, rate = choose(outcomes, set(persons))
    summary = {
        "set": "development",
        "persons": args.persons,
        "population_seed": args.seed,
        "library": Path(args.db).name,
        "switches_per_person": args.switches,
        "temper": temper,
        "switch_rate": rate,
        "switch_cost_sq_z": switch_cost(rate, skills, temper),
        "cross_validated": {k: rate_json(v) for k, v in held.items()},
        "grid": [
            {
                "temper": t,
                "switch_rate": r,
                "switch_cost_sq_z": switch_cost(r, skills, t),
                **{k: rate_json([ok for kind, _, ok in rows if kind == k]) for k in KINDS},
            }
            for (t, r), rows in outcomes.items()
        ],
        "switch_pairs": [[s.first, s.second, s.switch_time] for s in switched],
    }
    with atomic_output(Path(args.report), overwrite=args.overwrite) as tmp:
        tmp.write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps({k: v for k, v in summary.items() if k != "switch_pairs"}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

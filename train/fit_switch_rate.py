"""Fit the phase recogniser's switch rate on development persons, by what it is for.

The phase recogniser (:class:`~ias_gym.assist.phase_recogniser.PhaseRecogniser`) lets the
operator switch from one skill to another between two frames with a probability, its switch
rate (0: a session is one skill throughout). A low rate keeps the first skill's evidence
after the operator has changed their mind, and the session then ends as ``unknown`` (no
skill explains all of it); a high one lets a few odd frames of one skill's session look like
another skill, and a skill nobody stored like pieces of stored ones. So the rate is judged
on three kinds of session together, every one counted alike:

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
persons). Folds are groups of persons, each fold's rate
chosen on the others and its sessions reported with 95 % intervals. The rate chosen on all
persons is the report's ``switch_rate``; ``PHASE_SWITCH_RATE`` in
``ias_gym/assist/phase_recogniser.py`` holds it (a test compares the two).

    ias-gym assist library --db out/library.db --population 8 --population-seed 61
    python train/fit_switch_rate.py --db out/library.db --persons 16 --seed 7001 \
        --report out/switch_rate_fit.json
"""

from __future__ import annotations

import argparse
import json
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
from ias_gym.assist.phase_recogniser import PhaseRecogniser
from ias_gym.assist.recognition import UNKNOWN, LibrarySession, load_library
from ias_gym.errors import InputError
from ias_gym.glove.impairments import session_rng
from ias_gym.glove.population import population_ids
from ias_gym.glove.skills import SKILLS
from ias_gym.outputs import atomic_output, check_output_files
from ias_gym.rates import rate_json
from ias_gym.runtime.jobs import Backend, run_jobs
from ias_gym.skills import SkillDB

#: The rates searched [1/frame]. The frames' likelihoods are tempered
#: (:data:`~ias_gym.assist.phase_recogniser.PHASE_TEMPER`), so a switch costs twenty times its
#: log-odds in the novelty's units (:func:`~ias_gym.assist.phase_recogniser.switch_cost`):
#: from none, through rates whose switch costs as much as a few frames far off the model
#: (1e-60: about 2800, e.g. 35 frames at 10 squared z per feature), to one every second.
GRID = (0.0, 1e-60, 1e-40, 1e-30, 1e-20, 1e-12, 1e-8)
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

    def __call__(self, rate: float) -> list[tuple[str, str, bool]]:
        rows: list[tuple[str, str, bool]] = []
        rec = PhaseRecogniser(self.library, rate)
        at60 = FRACTIONS.index(0.6)
        for s in self.plain:
            r = score_trace(*posterior_trace(rec, s.frames), s)
            ok = r.correct_at[at60] and r.final == s.skill and not r.false_trigger
            rows.append(("plain", s.person_id, bool(ok)))
        latencies = evaluate_switches(rec, self.switched)["switch_latencies_s"]
        for w, latency in zip(self.switched, latencies, strict=True):
            rows.append(("switch", w.person_id, latency is not None))
        for skill in sorted({s.skill for s in self.library}):
            without = PhaseRecogniser([s for s in self.library if s.skill != skill], rate)
            for s in self.plain:
                if s.skill == skill:
                    post, _ = without.score_session(s.frames)
                    rows.append(("left out", s.person_id, post.best == UNKNOWN))
        return rows


KINDS = ("plain", "switch", "left out")


def choose(outcomes: dict[float, list[tuple[str, str, bool]]], persons: set[str]) -> float:
    """The rate with the most sessions right among ``persons`` (ties: the lowest)."""
    return max(outcomes, key=lambda r: (sum(ok for _, p, ok in outcomes[r] if p in persons), -r))


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
    ap.add_argument("--grid", default=",".join(f"{r:g}" for r in GRID), help="rates searched")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes")
    ap.add_argument("--report", required=True, help="JSON report written")
    ap.add_argument("--overwrite", action="store_true", help="replace --report")
    args = ap.parse_args(argv)
    try:
        try:
            grid = tuple(float(r) for r in args.grid.split(","))
        except ValueError:
            grid = ()
        if not grid or not all(0.0 <= r < 1.0 for r in grid):
            raise InputError(f"--grid {args.grid} must be comma-separated rates in [0, 1)")
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
    job = ScoreJob(library, plain, switched)
    scored = run_jobs(job, grid, backend, desc="rates", progress=True)
    outcomes = dict(zip(grid, scored, strict=True))
    folds = {p: i % args.folds for i, p in enumerate(persons)}
    held: dict[str, list[bool]] = {k: [] for k in KINDS}
    for fold in range(args.folds):
        rate = choose(outcomes, {p for p, f in folds.items() if f != fold})
        for kind, person, ok in outcomes[rate]:
            if folds[person] == fold:
                held[kind].append(ok)
    chosen = choose(outcomes, set(persons))
    summary = {
        "set": "development",
        "persons": args.persons,
        "population_seed": args.seed,
        "library": Path(args.db).name,
        "switches_per_person": args.switches,
        "switch_rate": chosen,
        "cross_validated": {k: rate_json(v) for k, v in held.items()},
        "grid": {
            f"{r:g}": {k: rate_json([ok for kind, _, ok in rows if kind == k]) for k in KINDS}
            for r, rows in outcomes.items()
        },
        "switch_pairs": [[s.first, s.second, s.switch_time] for s in switched],
    }
    with atomic_output(Path(args.report), overwrite=args.overwrite) as tmp:
        tmp.write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps({k: v for k, v in summary.items() if k != "switch_pairs"}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

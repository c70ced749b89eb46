"""The loop closed, measured: a skill the library lacks is demonstrated, acquired on line
and then completed for stopped operators, like a shipped skill.

Each skill with a motion of its own is in turn left out of the library (a copy of ``--db``
without its sessions). Demonstrators drawn from the population by ``--demonstrator-seed``
perform it one after the other in the glove world, unimpaired; after each demonstration the
assistant on observations (``make_assistant``, phase recogniser) runs acquisition mode
(``ObservationAssistant.learn``: stored as ``new_<skill>`` when its recogniser calls the
session unknown or ``new_<skill>``). After each, every evaluation person (drawn by
``--population-seed``) performs the skill in ``IAS-GloveAssist-v0``:

- stopped at 40 % of its motion (``stops:at=0.4``), assisted by the assistant as it now is;
- unimpaired, assisted: whether the assistant costs them anything, and whether its
  recogniser's final answer is the acquired skill.

Beside them, on the same persons: the stopped operator alone, and assisted by the assistant
on the whole library (the skill shipped, every library person's sessions of it).

    python train/assist_acquisition.py --db out/library.db --demonstrator-seed S1 \\
        --population-seed S2 --persons 30 --set held-out --out docs/assist_acquisition.json
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym

import ias_gym  # noqa: F401  (registers the envs)
from ias_gym.assist.assistance_evaluation import reference_session
from ias_gym.assist.policy import make_assistant
from ias_gym.assist.sessions import run_session, session_success
from ias_gym.assist.skill_motions import HOLD_SKILL, load_motions
from ias_gym.assist.stream import record_session
from ias_gym.envs.glove_assist import OBSERVATION_PARTS
from ias_gym.envs.layout import observation_layout
from ias_gym.glove.population import population_ids
from ias_gym.outputs import atomic_output, check_output_file
from ias_gym.rates import SET_KINDS, rate_json
from ias_gym.runtime.jobs import Backend, run_jobs
from ias_gym.skills.db import SkillDB

#: The impairment the acquired skill is completed against.
STOPS = "stops:at=0.4"


@dataclass(frozen=True)
class SkillJob:
    """A picklable job: one skill left out, acquired from the demonstrators, and measured on
    a share of the evaluation persons. Returns the job's record (see :func:`main`)."""

    skill: str
    db: str
    demonstrators: tuple[str, ...]
    reset_seed: int

    def __call__(self, persons: tuple[str, ...]) -> dict[str, Any]:
        layout = observation_layout(OBSERVATION_PARTS)
        rows: dict[str, Any] = {"persons": {}, "demonstrations": []}
        shipped = make_assistant(self.db, recogniser="phase", layout=layout)
        refs = {p: reference_session(p, self.skill, self.reset_seed) for p in persons}
        for p in persons:
            row: dict[str, Any] = {"reference": refs[p] is not None, "after": []}
            if refs[p] is not None:
                row["alone"] = self._stopped(p, None, refs[p])
                row["shipped"] = self._stopped(p, shipped, refs[p])
            rows["persons"][p] = row
        name = f"new_{self.skill}"
        with tempfile.TemporaryDirectory() as tmp:
            lib = Path(tmp) / "library.db"
            shutil.copyfile(self.db, lib)
            with SkillDB(lib) as db:
                for skill_id in db.ids():
                    if db.get(skill_id).name == self.skill:
                        db.delete(skill_id)
                assistant = make_assistant(lib, recogniser="phase", layout=layout)
                for demonstrator in self.demonstrators:
                    env = gym.make("IAS-GloveGrasp-v0", person_id=demonstrator, skill=self.skill)
                    try:
                        skill, frames = record_session(env, seed=self.reset_seed)
                    finally:
                        env.close()
                    entry: dict[str, Any] = {"person": demonstrator, "success": skill.is_success}
                    if skill.is_success:  # a failed demonstration is no skill to learn
                        result = assistant.learn(db, skill, frames, name)
                        entry.update(recognised=result.recognised, stored=result.stored_as)
                    rows["demonstrations"].append(entry)
                    for p in persons:
                        ref = refs[p]
                        if ref is None:
                            continue
                        stopped = self._stopped(p, assistant, ref)
                        env = gym.make("IAS-GloveAssist-v0", person_id=p, skill=self.skill)
                        whole = run_session(env, assistant, self.reset_seed)
                        env.close()
                        post = assistant.posterior()  # its last, at the session's end
                        rows["persons"][p]["after"].append(
                            {
                                "stopped": stopped,
                                "unimpaired": session_success(whole, ref),
                                "recognised": max(post, key=post.__getitem__) == name,
                            }
                        )
        return rows

    def _stopped(self, person: str, assistant: Any, ref: Any) -> bool:
        env = gym.make("IAS-GloveAssist-v0", person_id=person, skill=self.skill, impairment=STOPS)
        try:
            return session_success(run_session(env, assistant, self.reset_seed), ref)
        finally:
            env.close()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--db", required=True, help="skill library of development persons")
    ap.add_argument("--demonstrations", type=int, default=5, help="demonstrations per skill")
    ap.add_argument("--demonstrator-seed", type=int, required=True, help="their population seed")
    ap.add_argument("--persons", type=int, default=30, help="evaluation persons")
    ap.add_argument("--population-seed", type=int, required=True, help="their population seed")
    ap.add_argument("--set", choices=SET_KINDS, required=True, help="development or held-out")
    ap.add_argument("--skills", help="comma-separated skills (default: every moving one)")
    ap.add_argument("--reset-seed", type=int, default=0, help="reset seed of every session")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes")
    ap.add_argument("--out", required=True, help="JSON file written")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    args = ap.parse_args(argv)
    if not Path(args.db).is_file():
        print(f"--db {args.db} does not exist (build one: ias-gym assist library)", file=sys.stderr)
        return 2
    out = check_output_file(args.out, overwrite=args.overwrite, what="--out")
    moving = sorted(k for k in load_motions(args.db) if k != HOLD_SKILL)
    skills = args.skills.split(",") if args.skills else moving
    if unknown := set(skills) - set(moving):
        print(f"--skills {sorted(unknown)}: choose among {moving}", file=sys.stderr)
        return 2
    persons = population_ids(args.persons, args.population_seed)
    demonstrators = tuple(population_ids(args.demonstrations, args.demonstrator_seed))
    halves = [tuple(persons[: len(persons) // 2]), tuple(persons[len(persons) // 2 :])]
    jobs = [(s, h) for s in skills for h in halves if h]
    records = run_jobs(
        _Dispatch(args.db, demonstrators, args.reset_seed),
        jobs,
        Backend.from_options(args.workers),
        desc="skills x persons",
        progress=True,
    )
    table: dict[str, Any] = {
        "set": args.set,
        "persons": args.persons,
        "population_seed": args.population_seed,
        "demonstrator_seed": args.demonstrator_seed,
        "demonstrators": list(demonstrators),
        "library": Path(args.db).name,
        "impairment": STOPS,
        "by_skill": {},
    }
    pooled: dict[str, list[list[bool]]] = {}
    for skill in skills:
        mine = [r for (s, _), r in zip(jobs, records, strict=True) if s == skill]
        rows = [row for r in mine for row in r["persons"].values() if row["reference"]]
        n = len(mine[0]["demonstrations"])
        entry = {
            "demonstrations": mine[0]["demonstrations"],
            "excluded": sum(not row["reference"] for r in mine for row in r["persons"].values()),
            "stopped_alone": rate_json([row["alone"] for row in rows]),
            "stopped_shipped": rate_json([row["shipped"] for row in rows]),
        }
        for key in ("stopped", "unimpaired", "recognised"):
            curve = [[row["after"][k][key] for row in rows] for k in range(n)]
            entry[f"{key}_after"] = [rate_json(c) for c in curve]
            pooled.setdefault(key, [[] for _ in range(n)])
            for k in range(n):
                pooled[key][k] += curve[k]
        for key in ("alone", "shipped"):
            pooled.setdefault(key, [[]])[0] += [row[key] for row in rows]
        table["by_skill"][skill] = entry
    table["all"] = {
        "stopped_alone": rate_json(pooled["alone"][0]),
        "stopped_shipped": rate_json(pooled["shipped"][0]),
        **{
            f"{k}_after": [rate_json(c) for c in pooled[k]]
            for k in ("stopped", "unimpaired", "recognised")
        },
    }
    with atomic_output(Path(out), overwrite=args.overwrite) as tmp:
        tmp.write_text(json.dumps(table, indent=2) + "\n")
    print(json.dumps(table["all"], indent=2))
    return 0


@dataclass(frozen=True)
class _Dispatch:
    """``(skill, persons)`` -> :class:`SkillJob` of that skill on those persons."""

    db: str
    demonstrators: tuple[str, ...]
    reset_seed: int

    def __call__(self, job: tuple[str, tuple[str, ...]]) -> dict[str, Any]:
        skill, persons = job
        return SkillJob(skill, self.db, self.demonstrators, self.reset_seed)(persons)


if __name__ == "__main__":
    raise SystemExit(main())

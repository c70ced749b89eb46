"""Population table of the observation assistant: per impairment spec, success unassisted,
assisted with the recogniser and assisted without skill knowledge (and, with
``--residual``, assisted with a learned residual on top; with ``--without PART``, assisted
with one part of the assistant switched off), with 95 % intervals, on persons drawn by a
seed (``--set held-out``: one the fitting never saw). Beside each rate, each arm's
intervention: the mean over the judged sessions of
:attr:`~ias_gym.assist.sessions.SessionResult.intervention` (the size of the assistant's
offsets over the operator's own motion). ``--sessions FILE`` also keeps every judged
session: the impairment it drew, the arm and how it ended
(:func:`~ias_gym.assist.sessions.session_record`: where a pad came off the pen, the pose
errors, the lift's height): where the losses of a row sit, and what an arm changes.

    python train/assist_population.py --db out/library.db --persons 30 --seed S --set held-out \
        --impairment none --impairment stops:at=0.4 --out docs/assist_population.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import ias_gym  # noqa: F401  (registers the envs)
from ias_gym.assist.assistance_evaluation import reference_session
from ias_gym.assist.policy import make_assistant
from ias_gym.assist.sessions import run_session, session_record
from ias_gym.assist.skill_motions import load_motions
from ias_gym.envs.glove_assist import OBSERVATION_PARTS
from ias_gym.envs.layout import observation_layout
from ias_gym.errors import InputError
from ias_gym.glove.impairment_spec import expand_specs, parse_impairment
from ias_gym.glove.impairments import reference_kwargs
from ias_gym.glove.operator import OPERATORS
from ias_gym.glove.population import population_ids
from ias_gym.outputs import atomic_output, check_output_files
from ias_gym.rates import SET_KINDS, rate_json
from ias_gym.runtime.jobs import Backend, run_jobs

ARMS = ("unassisted", "assisted", "no_skill_knowledge")
#: The arm of a learned residual on the assistant (``--residual``).
RESIDUAL_ARM = "residual"


#: The assistant's parts an ablation arm switches off (``make_assistant``'s switches).
PARTS = ("pads", "tremor", "completion", "detection")


def arms_of(residual: str | None, without: tuple[str, ...] = ()) -> tuple[str, ...]:
    """The arms of a run: :data:`ARMS`, :data:`RESIDUAL_ARM` with a residual, and
    ``without_PART`` for each part switched off."""
    extra = (RESIDUAL_ARM,) if residual is not None else ()
    return (*ARMS, *extra, *(f"without_{part}" for part in without))


@dataclass(frozen=True)
class PersonJob:
    """A picklable job: one person's sessions, every spec, skill and arm.

    Returns every judged session's :func:`~ias_gym.assist.sessions.session_record` with the
    person, the spec, the spec the session drew (``sampled``: one family's), the skill and
    the arm; and the spec of each session left out for want of a reference."""

    specs: tuple[str, ...]
    skills: tuple[str, ...]
    db: str | None
    reset_seed: int
    operator: str = "closed_loop"
    residual: str | None = None
    without: tuple[str, ...] = ()

    def __call__(self, person: str) -> tuple[list[dict[str, Any]], list[str]]:
        layout = observation_layout(OBSERVATION_PARTS)
        assistants: dict[str, Any] = {
            "assisted": make_assistant(self.db, recogniser="phase", layout=layout),
            "no_skill_knowledge": make_assistant(self.db, recogniser="none", layout=layout),
        }
        for part in self.without:
            switches: dict[str, bool] = {part: False}
            assistants[f"without_{part}"] = make_assistant(
                self.db, "phase", None, layout=layout, **switches
            )
        arms = arms_of(self.residual, self.without)
        if self.residual is not None:
            from ias_gym.learning.assist_residual import ObservationResidualAssistant

            assistants[RESIDUAL_ARM] = ObservationResidualAssistant.load(self.residual, self.db)
        references: dict[tuple[str, str], Any] = {}
        records: list[dict[str, Any]] = []
        unjudged: list[str] = []
        for spec in self.specs:
            for skill in self.skills:
                env = gym.make(
                    "IAS-GloveAssist-v0",
                    person_id=person,
                    skill=skill,
                    impairment=spec,
                    operator=self.operator,
                )
                drawn = env.unwrapped.impairment  # type: ignore[attr-defined]
                same = reference_kwargs(drawn)
                key = (skill, repr(same))
                if key not in references:
                    references[key] = reference_session(
                        person, skill, self.reset_seed, **same, operator=self.operator
                    )
                ref = references[key]
                if ref is None:
                    unjudged.append(spec)
                for arm in arms if ref is not None else ():
                    result = run_session(env, assistants.get(arm), self.reset_seed)
                    records.append(
                        {
                            "person": person,
                            "spec": spec,
                            "drawn": drawn.spec,
                            "skill": skill,
                            "arm": arm,
                            **session_record(result, ref),
                        }
                    )
                env.close()
        return records, unjudged


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--db", help="skill library of development persons (default: the shipped one)")
    ap.add_argument("--persons", type=int, default=30, help="population persons")
    ap.add_argument("--seed", type=int, required=True, help="population seed")
    ap.add_argument(
        "--set", choices=SET_KINDS, required=True, help="development or held-out persons"
    )
    ap.add_argument("--impairment", action="append", help="spec, repeatable")
    ap.add_argument("--reset-seed", type=int, default=0, help="reset seed of every session")
    ap.add_argument(
        "--operator",
        choices=OPERATORS,
        default="closed_loop",
        help="the simulated person: in the loop, or the open script",
    )
    ap.add_argument(
        "--residual",
        help="a residual trained on the assistant (train/assist_residual.py --base observation)",
    )
    ap.add_argument(
        "--without",
        action="append",
        choices=PARTS,
        default=[],
        help="an arm assisted with this part switched off, repeatable",
    )
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes")
    ap.add_argument("--out", required=True, help="JSON file written")
    ap.add_argument(
        "--sessions", help="JSON file of every judged session, also written (default: none)"
    )
    ap.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    args = ap.parse_args(argv)
    if args.db is not None and not Path(args.db).is_file():
        print(f"--db {args.db} does not exist (build one: ias-gym assist library)", file=sys.stderr)
        return 2
    if args.residual is not None:
        from ias_gym.learning.assist_residual import check_base
        from ias_gym.safe_sb3 import PolicyFileError

        if not Path(args.residual).is_file():
            print(
                f"--residual {args.residual} does not exist (train/assist_residual.py)",
                file=sys.stderr,
            )
            return 2
        try:
            check_base(args.residual, "observation")
        except PolicyFileError as exc:
            print(f"--residual: {exc}", file=sys.stderr)
            return 2
    try:
        outputs = check_output_files(
            {"--out": args.out, "--sessions": args.sessions}, overwrite=args.overwrite
        )
    except InputError as exc:
        print(exc, file=sys.stderr)
        return 2
    out, sessions_out = Path(args.out), outputs["--sessions"]
    specs = expand_specs(args.impairment or ["none", "stops:at=0.4"])
    persons = population_ids(args.persons, args.seed)
    skills = sorted(load_motions(args.db))  # the skills with a motion of their own
    per_person = run_jobs(
        PersonJob(
            tuple(specs),
            tuple(skills),
            args.db,
            args.reset_seed,
            args.operator,
            args.residual,
            tuple(args.without),
        ),
        persons,
        Backend.from_options(args.workers),
        desc="persons",
        progress=True,
    )
    arms = arms_of(args.residual, tuple(args.without))
    outcomes: dict[str, dict[str, list[bool]]] = {s: {a: [] for a in arms} for s in specs}
    by_skill: dict[str, dict[str, list[bool]]] = {s: {k: [] for k in skills} for s in specs}
    by_family: dict[str, dict[str, dict[str, list[bool]]]] = {s: {} for s in specs}
    excluded = dict.fromkeys(specs, 0)
    sizes: dict[str, dict[str, list[float]]] = {s: {a: [] for a in arms} for s in specs}
    records = [r for person_records, _ in per_person for r in person_records]
    for spec in (s for _, unjudged in per_person for s in unjudged):
        excluded[spec] += 1
    for r in records:
        spec, arm, ok = r["spec"], r["arm"], bool(r["success"])
        family = parse_impairment(r["drawn"]).name
        outcomes[spec][arm].append(ok)
        sizes[spec][arm].append(float(r["intervention"]))
        by_family[spec].setdefault(family, {a: [] for a in arms})[arm].append(ok)
        if arm == "assisted":
            by_skill[spec][r["skill"]].append(ok)
    table = {
        "set": args.set,
        "persons": args.persons,
        "population_seed": args.seed,
        "library": Path(args.db).name if args.db else "shipped",
        "operator": args.operator,
        "residual": Path(args.residual).name if args.residual else None,
        "without": list(args.without),
        "skills": skills,
        "by_impairment": {
            spec: {
                **{arm: rate_json(outcomes[spec][arm]) for arm in arms},
                "excluded": excluded[spec],
                "intervention": {
                    arm: float(np.mean(v)) if v else None for arm, v in sizes[spec].items()
                },
                "assisted_by_skill": {k: rate_json(v) for k, v in by_skill[spec].items()},
                **(
                    {
                        "by_family": {
                            f: {a: rate_json(v) for a, v in per_arm.items()}
                            for f, per_arm in sorted(by_family[spec].items())
                        }
                    }
                    if len(by_family[spec]) > 1
                    else {}
                ),
            }
            for spec in specs
        },
    }
    with atomic_output(out, overwrite=args.overwrite) as tmp:
        tmp.write_text(json.dumps(table, indent=2) + "\n")
    if sessions_out is not None:
        with atomic_output(sessions_out, overwrite=args.overwrite) as tmp:
            tmp.write_text(json.dumps(records, indent=1) + "\n")
    print(json.dumps(table["by_impairment"], indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

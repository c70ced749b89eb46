"""Population table of the observation assistant: per impairment spec, success unassisted,
assisted with the recogniser and assisted without skill knowledge, with 95 % intervals, on
persons drawn by a seed (``--set held-out``: one the fitting never saw).

    python train/assist_population.py --persons 30 --seed S --set held-out \
        --impairment none --impairment stops:at=0.4 --out docs/assist_population.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import gymnasium as gym
from tqdm import tqdm

import ias_gym  # noqa: F401  (registers the envs)
from ias_gym.assist.assistance_evaluation import reference_session
from ias_gym.assist.policy import make_assistant
from ias_gym.assist.sessions import run_session, session_success
from ias_gym.assist.skill_motions import load_motions
from ias_gym.envs.glove_assist import OBSERVATION_PARTS
from ias_gym.envs.layout import observation_layout
from ias_gym.glove.impairment_spec import expand_specs
from ias_gym.glove.impairments import reference_kwargs
from ias_gym.glove.population import population_ids
from ias_gym.outputs import atomic_output, check_output_file
from ias_gym.rates import SET_KINDS, Rate

ARMS = ("unassisted", "assisted", "no_skill_knowledge")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--persons", type=int, default=30, help="population persons")
    ap.add_argument("--seed", type=int, required=True, help="population seed")
    ap.add_argument(
        "--set", choices=SET_KINDS, required=True, help="development or held-out persons"
    )
    ap.add_argument("--impairment", action="append", help="spec, repeatable")
    ap.add_argument("--reset-seed", type=int, default=0, help="reset seed of every session")
    ap.add_argument("--out", required=True, help="JSON file written")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    args = ap.parse_args(argv)
    out = check_output_file(args.out, overwrite=args.overwrite, what="--out")
    specs = expand_specs(args.impairment or ["none", "stops:at=0.4"])
    persons = population_ids(args.persons, args.seed)
    skills = sorted(load_motions())  # the skills with a motion of their own
    layout = observation_layout(OBSERVATION_PARTS)
    assistants = {
        "assisted": make_assistant(recogniser="phase", layout=layout),
        "no_skill_knowledge": make_assistant(recogniser="none", layout=layout),
    }
    outcomes: dict[str, dict[str, list[bool]]] = {s: {a: [] for a in ARMS} for s in specs}
    excluded = dict.fromkeys(specs, 0)
    references: dict[Any, Any] = {}
    with tqdm(total=len(specs) * len(persons) * len(skills), desc="sessions") as bar:
        for spec in specs:
            for person in persons:
                for skill in skills:
                    env = gym.make(
                        "IAS-GloveAssist-v0", person_id=person, skill=skill, impairment=spec
                    )
                    same = reference_kwargs(env.unwrapped.impairment)  # type: ignore[attr-defined]
                    key = (person, skill, repr(same))
                    if key not in references:
                        references[key] = reference_session(person, skill, args.reset_seed, **same)
                    ref = references[key]
                    if ref is None:
                        excluded[spec] += 1
                    else:
                        for arm in ARMS:
                            assistant = assistants.get(arm)
                            result = run_session(env, assistant, args.reset_seed)
                            outcomes[spec][arm].append(session_success(result, ref))
                    env.close()
                    bar.update()
    table = {
        "set": args.set,
        "persons": args.persons,
        "population_seed": args.seed,
        "skills": skills,
        "by_impairment": {
            spec: {
                **{arm: Rate.of(outcomes[spec][arm]).to_dict() for arm in ARMS},
                "excluded": excluded[spec],
            }
            for spec in specs
        },
    }
    with atomic_output(Path(out), overwrite=args.overwrite) as tmp:
        tmp.write_text(json.dumps(table, indent=2) + "\n")
    print(json.dumps(table["by_impairment"], indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""``ias-gym assist ...``: intent recognition of glove sessions (issue #14, paper Flow 3).

``assist recognise`` builds the recognisers on the glove sessions of a skill database,
records sessions of held-out persons and reports accuracy over the observed fraction of the
skill's motion, time to recognise, false triggers and the unknown-skill AUROC
(:mod:`ias_gym.assist.metrics`). The library is imported when the command runs.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from ias_gym.cli.args import HelpFormatter, non_negative_int, positive_int
from ias_gym.errors import InputError

#: The recognition keys of ``assist recognise --json`` (per method).
RECOGNITION_KEYS = (
    "recog_acc_at_33",
    "recog_acc_at_60",
    "time_to_recognise_s",
    "false_trigger_rate",
    "unknown_auroc",
)


def _recognise(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from ias_gym.assist.metrics import check_held_out, evaluate_methods, record_sessions
    from ias_gym.assist.recognition import METHODS, load_library
    from ias_gym.glove.ids import check_id
    from ias_gym.glove.skills import SKILLS
    from ias_gym.skills import SkillDB

    methods = list(METHODS) if args.method == "all" else [args.method]
    if args.method != "all" and args.method not in METHODS:
        raise InputError(f"--method {args.method!r}: choose one of {', '.join(METHODS)} or all")
    persons = [p.strip() for p in args.persons.split(",") if p.strip()]
    if not persons:
        raise InputError("--persons needs at least one person id, e.g. --persons h1,h2")
    for p in persons:
        check_id(p, "--persons id")
    db_path = Path(args.db)
    if not db_path.is_file():
        raise InputError(
            f"--db {db_path}: no such file; record a library with `ias-gym skills record`"
        )
    with SkillDB(db_path, readonly=True) as db:
        library = load_library(db)
    check_held_out(library, persons)
    skills = [s for s in SKILLS if s in {x.skill for x in library}]
    if not skills:
        raise InputError(f"--db {db_path} holds no session of the glove skills {', '.join(SKILLS)}")
    bar: Any = None if args.json else tqdm
    sessions = record_sessions(persons, skills, args.episodes, seed=args.seed, progress=bar)
    results = evaluate_methods(library, sessions, methods, progress=bar)
    if args.json:
        payload = results[methods[0]] if len(methods) == 1 else {"methods": results}
        print(json.dumps(payload))
        return 0
    width = max(len(k) for k in RECOGNITION_KEYS)
    print(f"{'':<{width}}  " + "  ".join(f"{m:>8}" for m in methods))
    for key in RECOGNITION_KEYS:
        cells = []
        for m in methods:
            v = results[m][key]
            cells.append(f"{'-':>8}" if v is None else f"{v:8.3f}")
        print(f"{key:<{width}}  " + "  ".join(cells))
    sys.stdout.flush()
    return 0


def add_assist_commands(subparsers: argparse._SubParsersAction[Any]) -> None:
    """Add ``assist`` and its sub-commands.

    Args:
        subparsers: the object ``parser.add_subparsers(...)`` returned; each parser sets
            ``run`` (``args -> exit code``) as its default.
    """
    assist = subparsers.add_parser(
        "assist",
        help="intent recognition and assistance of glove sessions (paper Flow 3)",
        description="Recognise the skill a glove session performs (and unknown ones).",
        formatter_class=HelpFormatter,
    )
    commands = assist.add_subparsers(dest="assist_command", metavar="COMMAND", required=True)
    recognise = commands.add_parser(
        "recognise",
        help="evaluate the recognisers on held-out persons",
        description="Build the recognisers on the IAS-GloveGrasp-v0 sessions of --db, record "
        "--episodes sessions of each of its glove skills for every person of --persons (who "
        "must not be in the library) and report accuracy after 33 % and 60 % of the skill's "
        "motion, time to recognise, false triggers and the unknown-skill AUROC (each skill "
        'left out in turn). With --json: one object (per method under "methods" for all).',
        formatter_class=HelpFormatter,
    )
    recognise.add_argument("--db", required=True, metavar="FILE", help="the skill library")
    recognise.add_argument(
        "--persons", required=True, metavar="ID,ID", help="held-out person ids to record"
    )
    recognise.add_argument(
        "--method", default="all", metavar="dtw|phase|all", help="the recogniser(s)"
    )
    recognise.add_argument(
        "--episodes",
        type=positive_int,
        default=2,
        metavar="N",
        help="sessions per person and skill",
    )
    recognise.add_argument(
        "--seed",
        type=non_negative_int,
        default=1000,
        metavar="S",
        help="reset seed of the first session",
    )
    recognise.add_argument("--json", action="store_true", help="print one JSON object")
    recognise.set_defaults(run=_recognise)

"""``ias-gym assist ...``: intent recognition and assistance of glove sessions.

``assist recognise`` builds the recognisers on the glove sessions of a skill database,
records sessions of held-out persons and reports accuracy over the observed fraction of the
skill's motion, time to recognise, false triggers and the unknown-skill AUROC
(:mod:`ias_gym.assist.metrics`). The library is imported when the command runs.

``assist evaluate`` runs ``IAS-GloveAssist-v0`` sessions with and without the analytic
assistant per operator impairment; with ``--json`` the last line is one object with the
recognition keys (the recogniser the assistant uses, :data:`ASSIST_METHOD`, on the same
persons; null when they are in the library) and ``by_impairment``: impairment ->
``success_unassisted``, ``success_assisted``, ``intervention``. ``assist demo``:
:mod:`ias_gym.cli.assist_demo`.

``assist acquire`` records one demonstration in the glove world and runs the assistant's
acquisition mode on it (:meth:`~ias_gym.assist.policy.ObservationAssistant.learn`): stored in
the library as ``--name`` when the recogniser calls it unknown or ``--name``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

from ias_gym.cli.args import HelpFormatter, episode_arguments, int_at_least, non_negative_int
from ias_gym.cli.assist_demo import (
    ASSIST_METHOD,
    add_assist_demo,
    add_assistant_argument,
    add_operator_argument,
    assistant_factory,
)
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
    from ias_gym.assist.recogniser_registry import METHODS
    from ias_gym.assist.recognition import load_library
    from ias_gym.glove.skills import SKILLS
    from ias_gym.skills import SkillDB

    methods = list(METHODS) if args.method == "all" else [args.method]
    if args.method != "all" and args.method not in METHODS:
        raise InputError(f"--method {args.method!r}: choose one of {', '.join(METHODS)} or all")
    persons = _persons_of(args, None)
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


def _library(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from ias_gym.assist.metrics import record_sessions
    from ias_gym.glove.skills import SKILLS
    from ias_gym.skills import SkillDB

    persons = _persons_of(args, LIBRARY_POPULATION)
    skills = SKILLS if args.skills == "all" else [s.strip() for s in args.skills.split(",")]
    for s in skills:
        if s not in SKILLS:
            raise InputError(f"--skills {s!r}: choose from {', '.join(SKILLS)} or all")
    Path(args.db).parent.mkdir(parents=True, exist_ok=True)
    with SkillDB(args.db) as db:  # a corrupt file is refused here, before any session runs
        before = len(db)
        record_sessions(persons, skills, args.episodes, seed=args.seed, db=db, progress=tqdm)
        after = len(db)
    print(f"{args.db}: {after - before} sessions added ({after} in all)")
    return 0


def _acquire(args: argparse.Namespace) -> int:
    import gymnasium as gym

    import ias_gym  # noqa: F401 - registers the envs
    from ias_gym.assist.policy import make_assistant
    from ias_gym.assist.recogniser_registry import METHODS
    from ias_gym.assist.recognition import check_skill_name
    from ias_gym.assist.stream import record_session
    from ias_gym.glove.ids import check_id
    from ias_gym.glove.skills import check_skill
    from ias_gym.skills import SkillDB

    check_id(args.person, "--person")
    check_skill(args.skill, "--skill")
    check_skill_name(args.name, "--name")
    if args.method not in METHODS:  # before the session is recorded
        raise InputError(f"--method {args.method!r}: choose one of {', '.join(METHODS)}")
    if not Path(args.db).is_file():
        raise InputError(f"--db {args.db} does not exist (build one: ias-gym assist library)")
    assistant = make_assistant(args.db, recogniser=args.method)
    env = gym.make("IAS-GloveGrasp-v0", person_id=args.person, skill=args.skill)
    try:
        skill, frames = record_session(env, seed=args.seed)
    finally:
        env.close()
    if not skill.is_success:
        raise InputError(
            f"{args.person}'s {args.skill} demonstration failed (the pen was not held to the "
            "end): nothing stored; demonstrate again (another --seed or --person)"
        )
    with SkillDB(args.db) as db:
        result = assistant.learn(db, skill, frames, args.name)
    if args.json:
        print(json.dumps(dataclasses.asdict(result)))
    elif result.stored_as is None:
        print(f"recognised as {result.recognised}, a known skill: not stored")
    else:
        print(
            f"recognised as {result.recognised}: stored as {result.stored_as} "
            f"(id {result.skill_id} in {args.db})"
        )
    return 0


#: The persons of ``assist library`` and ``assist evaluate`` when ``--persons`` is not given:
#: ``(N, seed)`` of a population draw. The two seeds differ, so that the default evaluation
#: persons are never the default library's.
LIBRARY_POPULATION = (5, 0)
EVALUATION_POPULATION = (3, 1)


def _persons_of(args: argparse.Namespace, default: tuple[int, int] | None) -> list[str]:
    """The persons of ``--persons ID,ID`` or of the population draw ``--population N
    --population-seed S`` (``default`` gives N and S where they are not given; ``None``:
    one of the two must be given).

    Raises:
        InputError: both given, neither (without a default), an empty list or a bad id.
    """
    from ias_gym.glove.ids import check_id
    from ias_gym.glove.population import population_ids

    if args.persons is None:
        if args.population is not None:
            n = args.population
        elif default is not None:
            n = default[0]
        else:
            raise InputError("give the persons: --persons ID,ID,... or --population N")
        seed = args.population_seed
        if seed is None:
            seed = default[1] if default is not None else 0
        return population_ids(n, seed)
    if args.population is not None or args.population_seed is not None:
        raise InputError("--persons and --population exclude each other: give one of them")
    persons = [p.strip() for p in args.persons.split(",") if p.strip()]
    if not persons:
        raise InputError("--persons needs at least one person id, e.g. ana,ben")
    return [check_id(p, "--persons") for p in persons]


def _person_arguments(parser: argparse.ArgumentParser, default: tuple[int, int] | None) -> None:
    """``--persons`` and the population draw that replaces it (``default``: its N and seed;
    ``None``: no default, one of the two is required)."""
    n, seed = default if default is not None else ("none: give it or --persons", 0)
    parser.add_argument(
        "--persons",
        default=None,
        metavar="ID,ID,...",
        help="person ids (default: the --population draw)" if default else "person ids",
    )
    parser.add_argument(
        "--population",
        type=int_at_least(1),
        metavar="N",
        help=f"N persons drawn from the population (docs/population.md) (default: {n})",
    )
    parser.add_argument(
        "--population-seed",
        type=non_negative_int,
        metavar="S",
        help="seed of the --population draw: the same seed gives the same persons "
        f"(default: {seed})",
    )


def _impairments(specs: list[str] | None) -> list[str]:
    """The ``--impairment`` specs, ``all`` expanded (default: ``none`` and every family)."""
    from ias_gym.glove.impairment_spec import expand_specs

    try:
        return expand_specs(specs or ["none", "all"])
    except InputError as e:
        raise InputError(f"--impairment: {e}") from None


def _recognition_metrics(db: Path, persons: list[str], episodes: int, seed: int) -> dict[str, Any]:
    """The better recogniser's metrics (:mod:`ias_gym.assist.metrics`) on ``episodes``
    sessions per skill of ``persons``; nulls if they are in the library (not held out)."""
    from ias_gym.assist.metrics import evaluate_methods, record_sessions
    from ias_gym.assist.recognition import load_library
    from ias_gym.glove.skills import SKILLS
    from ias_gym.skills import SkillDB

    with SkillDB(db, readonly=True) as handle:
        library = load_library(handle)
    if {s.group for s in library} & set(persons):
        return dict.fromkeys(RECOGNITION_KEYS)
    skills = [s for s in SKILLS if s in {x.skill for x in library}]
    sessions = record_sessions(persons, skills, episodes, seed=seed)
    result = evaluate_methods(library, sessions, [ASSIST_METHOD])[ASSIST_METHOD]
    return {k: result.get(k) for k in RECOGNITION_KEYS}


def _evaluate(args: argparse.Namespace) -> int:
    persons = _persons_of(args, EVALUATION_POPULATION)
    impairments = _impairments(args.impairment)
    db = Path(args.db)
    if not db.is_file():
        raise InputError(f"--db {db} does not exist; give a skill library (skills record)")
    from tqdm import tqdm

    from ias_gym.assist.assistance_evaluation import evaluate_assistance

    make = assistant_factory(args.assistant, args.recogniser, db)
    total = len(persons) * len(impairments) * args.episodes
    with tqdm(total=total, desc="sessions", disable=args.json, file=sys.stderr) as bar:
        scores = evaluate_assistance(
            make,
            persons,
            impairments,
            args.episodes,
            args.seed,
            progress=lambda: bar.update(1),
            operator=args.operator,
        )
    if args.json:
        out = _recognition_metrics(db, persons, max(1, args.episodes // 6), args.seed)
        out["by_impairment"] = {k: v.to_json() for k, v in scores.items()}
        print(json.dumps(out))
    else:
        for name, s in scores.items():
            print(
                f"{name}: success {100 * s.success_unassisted:.0f} % unassisted, "
                f"{100 * s.success_assisted:.0f} % assisted, intervention "
                f"{s.intervention:.3f} ({s.sessions} sessions, {s.excluded} left out: the "
                "unimpaired session failed itself, or from a start 1e-9 away)"
            )
    return 0


def add_assist_evaluate(commands: argparse._SubParsersAction[Any]) -> argparse.ArgumentParser:
    """Add ``assist evaluate`` to the ``assist`` sub-commands.

    Args:
        commands: the ``assist`` group's sub-parsers.

    Returns:
        The parser.
    """
    p = commands.add_parser(
        "evaluate",
        help="success with and without the assistant per impairment",
        description="Run IAS-GloveAssist-v0 sessions of every skill for each person and "
        "impairment, without and with the assistant (--assistant), and judge them against the "
        "unimpaired person's session (docs/assistance.md). With --json the last line is "
        "one object: " + ", ".join(RECOGNITION_KEYS) + " and by_impairment.",
        formatter_class=HelpFormatter,
    )
    p.add_argument(
        "--db", required=True, metavar="F", help="the skill library (`ias-gym assist library`)"
    )
    _person_arguments(p, EVALUATION_POPULATION)
    p.add_argument(
        "--impairment",
        action="append",
        metavar="SPEC",
        help="an impairment, repeatable: NAME, NAME:KEY=VALUE[,KEY=VALUE], A+B, none, "
        "sampled or all (every family); keys: tremor hz, amplitude_rad; weak_grip fingers="
        "index|thumb|both, rad; lag s; biased_calibration rad (signed), fingers; hand_size "
        "scale; stops at (default: none and all)",
    )
    episode_arguments(p, 6, "sessions per person", seed_help="first seed")
    add_assistant_argument(p, "observation")
    add_operator_argument(p)
    p.add_argument(
        "--recogniser",
        default=ASSIST_METHOD,
        metavar="phase|dtw|none|oracle",
        help="how the assistant knows the intent (none: no skill knowledge; oracle, analytic "
        "only: the true skill)",
    )
    p.add_argument("--json", action="store_true", help="one JSON object on the last line")
    p.set_defaults(run=_evaluate)
    return p


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
    _person_arguments(recognise, None)
    recognise.add_argument(
        "--method", default="all", metavar="dtw|phase|all", help="the recogniser(s)"
    )
    episode_arguments(recognise, 2, "sessions per person and skill", seed=1000)
    recognise.add_argument("--json", action="store_true", help="print one JSON object")
    recognise.set_defaults(run=_recognise)
    library = commands.add_parser(
        "library",
        help="record a recognition library (every skill, each person)",
        description="Record --episodes teleoperated IAS-GloveGrasp-v0 sessions of each skill "
        "for every person of --persons into --db (created if missing, else added to), with "
        "the glove's readings and calibrated angles the recognisers read. A library needs "
        "several persons: its unknown threshold is calibrated leave-one-person-out (the "
        "shipped two-person library calls most sessions of a new person unknown).",
        formatter_class=HelpFormatter,
    )
    library.add_argument("--db", required=True, metavar="FILE", help="the skill database")
    _person_arguments(library, LIBRARY_POPULATION)
    library.add_argument(
        "--skills", default="all", metavar="NAME,...|all", help="the skills to record"
    )
    episode_arguments(
        library, 2, "sessions per person and skill", seed_help="reset seed of the first"
    )
    library.set_defaults(run=_library)
    acquire = commands.add_parser(
        "acquire",
        help="demonstrate a skill and let the assistant acquire it",
        description="Record one IAS-GloveGrasp-v0 session of --person performing --skill and "
        "run acquisition mode on it: the library's recogniser scores the whole session, and "
        "it is stored in --db as --name when it is called unknown (a skill the library lacks) "
        "or --name (more sessions of it); one recognised as another known skill is not "
        "stored. From then on the assistant on --db recognises and completes --name. A failed "
        "demonstration is not stored (exit 2).",
        formatter_class=HelpFormatter,
    )
    acquire.add_argument("--db", required=True, metavar="FILE", help="the assistant's library")
    acquire.add_argument("--person", required=True, metavar="ID", help="who demonstrates")
    acquire.add_argument("--skill", required=True, metavar="NAME", help="what they perform")
    acquire.add_argument("--name", required=True, metavar="NAME", help="the acquired skill's name")
    acquire.add_argument(
        "--method", default=ASSIST_METHOD, metavar="phase|dtw", help="the recogniser"
    )
    acquire.add_argument(
        "--seed", type=non_negative_int, default=0, metavar="S", help="the session's reset seed"
    )
    acquire.add_argument("--json", action="store_true", help="print one JSON object")
    acquire.set_defaults(run=_acquire)
    add_assist_evaluate(commands)
    add_assist_demo(commands)

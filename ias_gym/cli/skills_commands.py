"""The ``ias-gym skills`` command group: record, merge, list, show, export, export-pen-skill
(the expert's executions of the human skills on each hand, as Minari), check, delete,
migrate.

:func:`add_skills_commands` adds the group to the ``ias-gym`` parser's sub-commands; each
handler takes the parsed arguments and returns an exit code (0 ok; ``check``: 2 when a skill
is corrupt). An error raises :class:`~ias_gym.errors.IasGymError` (bad input:
:class:`~ias_gym.errors.InputError`), which the ``ias-gym`` command prints as one line.
Handlers import what they need when they run, so ``--help`` stays fast.

``list``, ``show``, ``export`` and ``check`` open the database read-only
(``SkillDB(path, readonly=True)``): they never create a file or a folder, and refuse a
missing path or an empty file. ``delete`` and ``migrate`` open an existing database for
writing; only ``record`` creates one.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ias_gym.cli.args import (
    HelpFormatter,
    backend_from_args,
    env_kwargs_argument,
    overwrite_argument,
    parallel_arguments,
    parse_env_kwargs,
    policy_arguments,
)
from ias_gym.cli.transfer_command import add_transfer_command
from ias_gym.errors import IasGymError, InputError
from ias_gym.glove.population import population_ids
from ias_gym.glove.skills import SKILLS

#: Exit code of ``skills check`` when a skill is corrupt.
EXIT_CORRUPT = 2


@contextmanager
def _as_package_errors() -> Iterator[None]:
    """Re-raise the library's other expected errors as :class:`IasGymError` (one line).

    ValueError (bad arguments, a policy that does not fit the env), FileNotFoundError and
    FileExistsError become :class:`InputError`; ImportError (a missing extra) an
    IasGymError with the install hint. The package's own errors pass unchanged.
    """
    try:
        yield
    except IasGymError:
        raise
    except (ValueError, FileNotFoundError, FileExistsError) as exc:
        raise InputError(str(exc)) from exc
    except ImportError as exc:
        raise IasGymError(str(exc)) from exc


def _record(args: argparse.Namespace) -> int:
    from ias_gym.skills.record import record_skills_spec

    backend = backend_from_args(args)  # a missing Ray extra fails before any work
    persons: list[str | None] = [args.person]
    if args.population is not None:
        if args.person is not None:
            raise InputError("--person and --population exclude each other: give one of them")
        persons = list(population_ids(args.population, args.population_seed))
    ids: list[int] = []
    with _as_package_errors():
        env_kwargs = parse_env_kwargs(args.env_kwargs)
        for person in persons:
            ids += record_skills_spec(
                args.env,
                args.policy,
                args.episodes,
                Path(args.db),
                seed=args.seed,
                progress=not args.no_progress,
                env_kwargs=env_kwargs,
                person_id=person,
                skill=args.skill,
                trust_pickle=args.trust_pickle,
                backend=backend,
            )
    print(f"stored {len(ids)} skills (ids {', '.join(map(str, ids))}) in {args.db}")
    return 0


def _merge(args: argparse.Namespace) -> int:
    from ias_gym.skills.db_merge import merge_databases

    counts = merge_databases(args.out, args.dbs, overwrite=args.overwrite)
    parts = ", ".join(f"{n} from {db}" for n, db in zip(counts, args.dbs, strict=True))
    print(f"wrote {sum(counts)} skills to {args.out} ({parts})")
    return 0


def _list(args: argparse.Namespace) -> int:
    from ias_gym.skills.db import SkillDB

    success = True if args.success_only else None
    with SkillDB(args.db, readonly=True) as db:
        skills = db.list_skills(task=args.task, success=success)
    if args.json:
        keys = ("id", "name", "task", "source", "is_success", "return", "length", "created")
        print(json.dumps([{k: s.to_dict()[k] for k in keys} for s in skills]))
        return 0
    if not skills:
        print(f"no skills in {args.db}" + (f" for task {args.task}" if args.task else ""))
        return 0
    print(f"{'id':>5}  {'task':<20} {'source':<12} {'ok':<3} {'return':>9} {'steps':>6}  created")
    for s in skills:
        ok = "yes" if s.is_success else "no"
        print(
            f"{s.id:>5}  {s.task:<20} {s.source[:12]:<12} {ok:<3} {s.episode_return:>9.3f} "
            f"{s.length:>6}  {s.created}"
        )
    print(f"{len(skills)} skills in {args.db}")
    return 0


def _show(args: argparse.Namespace) -> int:
    from ias_gym.skills.db import SkillDB

    with SkillDB(args.db, readonly=True) as db:
        skill = db.get(args.id)
        summary = db.summary(args.id)
    info: dict[str, Any] = summary.to_dict()
    info["model"] = skill.model.summary()
    info["observation_shape"] = list(skill.demonstration.observations.shape)
    info["action_shape"] = list(skill.demonstration.actions.shape)
    info["infos"] = sorted(skill.demonstration.infos)
    if args.json:
        print(json.dumps(info))
        return 0
    model = info["model"]
    print(f"skill {summary.id}: {summary.name}")
    print(f"  task {summary.task}  env kwargs {summary.env_kwargs}")
    print(
        f"  source {summary.source}  person {summary.person_id or '-'}  seed {summary.seed}  "
        f"created {summary.created}  ias-gym {summary.package_version}"
    )
    print(
        f"  success {summary.is_success}  return {summary.episode_return:.4g}  "
        f"{summary.length} steps  duration {model['duration']:.3f} s"
    )
    print("  contact schedule [s]:")
    for finger in model["fingers"]:
        print(
            f"    finger {finger['finger']}: touching {finger['touching_fraction']:.0%} "
            f"{_spans(finger['touching'])}; sliding {_spans(finger['sliding'])}"
            + (
                "; normal force [{:.3f}, {:.3f}] N".format(*finger["normal_force_range"])
                if "normal_force_range" in finger
                else ""
            )
        )
    defined = f"{model['grip_transform_defined_fraction']:.0%} of the samples"
    if skill.model.is_pinch:  # two fingers: no G (rank W <= 5), one internal force
        print(f"  pinch squeeze f_int defined (both fingers touch, rank W = 5) in {defined}")
    else:
        print(f"  grip transform defined (rank W = 6) in {defined}")
    for i, span in enumerate(model["f_int_range"], start=1):
        text = "undefined" if span is None else f"[{span[0]:+.4f}, {span[1]:+.4f}]"
        print(f"  f_int[{i}] {text} N")
    if model["c_h_norm_range"] is not None:
        print("  |c_h| [{:.4f}, {:.4f}] N".format(*model["c_h_norm_range"]))
    print(f"  pen: largest excursion {model['max_pen_excursion'] * 1e3:.2f} mm")
    return 0


def _spans(intervals: list[list[float]]) -> str:
    if not intervals:
        return "never"
    shown = ", ".join(f"{a:.2f}-{b:.2f}" for a, b in intervals[:4])
    return shown + (f" (+{len(intervals) - 4} more)" if len(intervals) > 4 else "")


def _export(args: argparse.Namespace) -> int:
    from ias_gym.skills.minari_export import export_minari

    with _as_package_errors():
        path = export_minari(
            args.db, args.dataset_id, task=args.task, success_only=args.success_only
        )
    print(f"wrote Minari dataset {args.dataset_id} to {path}")
    return 0


def _export_pen_skill(args: argparse.Namespace) -> int:
    from ias_gym.sim.hands import get_hand, hand_names
    from ias_gym.skills.minari_export import (
        export_pen_skill_dataset,
        pen_skill_dataset_exists,
        pen_skill_dataset_id,
    )

    hands = hand_names() if args.hand == "all" else [get_hand(args.hand).name]
    for option, value in (("--dataset-id", args.dataset_id), ("--db", args.db)):
        if value is not None and len(hands) > 1:
            raise InputError(f"{option} is for one hand's executions: give one --hand with it")
    if args.episodes_per_skill < 1:
        raise InputError(f"--episodes-per-skill must be >= 1, got {args.episodes_per_skill}")
    skill_ids = None if args.skill_ids is None else _parse_ids(args.skill_ids, "--skill-ids")
    with _as_package_errors():
        ids = {hand: args.dataset_id or pen_skill_dataset_id(hand) for hand in hands}
        for dataset_id in ids.values():  # every output checked before any work
            if pen_skill_dataset_exists(dataset_id):
                raise InputError(
                    f"a Minari dataset {dataset_id!r} exists already; remove it "
                    "(minari delete ID) or give another --dataset-id"
                )
        for hand, dataset_id in ids.items():
            path = export_pen_skill_dataset(
                dataset_id,
                hand=hand,
                episodes_per_skill=args.episodes_per_skill,
                db_path=args.db,
                skill_ids=skill_ids,
            )
            print(f"wrote Minari dataset {dataset_id} ({hand}) to {path}", flush=True)
    return 0


def _parse_ids(text: str, option: str) -> list[int]:
    """Comma-separated skill ids (``"1,4,9"``); a bad one is an :class:`InputError`."""
    try:
        ids = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        message = f"{option} takes comma-separated skill ids, e.g. 1,4,9; got {text!r}"
        raise InputError(message) from None
    if not ids or min(ids) < 1:
        raise InputError(f"{option} takes skill ids >= 1, e.g. 1,4,9; got {text!r}")
    return ids


def _check(args: argparse.Namespace) -> int:
    def report(skill_id: int, problem: str | None) -> None:
        if args.json:
            print(json.dumps({"id": skill_id, "ok": problem is None, "error": problem}))
        else:
            print(f"skill {skill_id}: {'OK' if problem is None else problem}", flush=True)

    from ias_gym.skills.check import check_database

    bad = check_database(args.db, report)
    if not args.json:
        verdict = "all OK" if bad == 0 else f"{bad} corrupt"
        print(f"checked {args.db}: {verdict}")
    return EXIT_CORRUPT if bad else 0


def _delete(args: argparse.Namespace) -> int:
    from ias_gym.skills.db import SkillDB

    with SkillDB(args.db, create=False) as db:
        name = db.delete(args.id)
        left = len(db)
    print(f"deleted skill {args.id} ({name}) from {args.db}; {left} skills left")
    return 0


def _migrate(args: argparse.Namespace) -> int:
    from ias_gym.skills.db import SCHEMA_VERSION, SkillDB
    from ias_gym.skills.glove_session import describe_session

    with SkillDB(args.db, readonly=True) as db:  # read the version without changing it
        before = db.schema_version
    with SkillDB(args.db, create=False) as db:  # opening for writing migrates
        after, count = db.schema_version, len(db)
        described, left = 0, []
        for skill_id in db.ids():  # then each session gets what it lacks of its description
            infos, person, why = describe_session(db.get(skill_id))
            if why:
                left.append(f"skill {skill_id}: {why}")
            elif infos or person is not None:
                db.describe(skill_id, infos=infos, person_params=person)
                described += 1
    if before == SCHEMA_VERSION and not described:
        print(f"{args.db} is at schema version {SCHEMA_VERSION}; nothing to do")
    else:
        print(
            f"migrated {args.db} from schema version {before} to {after} ({count} skills; "
            f"{described} given their intended motion and person)"
        )
    for line in left:
        print(f"  left as it is: {line}")
    return 0


def add_skills_commands(subparsers: argparse._SubParsersAction[Any]) -> argparse.ArgumentParser:
    """Add ``skills`` with its sub-commands ``record``, ``merge``, ``list``, ``show``,
    ``export``, ``check``, ``delete`` and ``migrate``.

    Args:
        subparsers: the object ``parser.add_subparsers(...)`` returned; each leaf parser
            sets ``run`` (``args -> exit code``) as its default.

    Returns:
        The ``skills`` parser.
    """
    skills = subparsers.add_parser(
        "skills",
        help="the skill database: record, list, show, export, check and delete skills",
        description="Skills (paper sec. 3: contact schedule, object trajectory and the "
        "internal forces of G(t)) with their demonstrations, in an SQLite file.",
    )
    commands = skills.add_subparsers(dest="skills_command", metavar="SUBCOMMAND", required=True)

    def db_argument(p: argparse.ArgumentParser, what: str = "an existing skill database") -> None:
        p.add_argument("--db", required=True, metavar="PATH", help=f"{what} (required)")

    record = commands.add_parser(
        "record",
        help="roll out a policy and store every episode as a skill",
        description="Run N seeded episodes (seeds S, S+1, ...) and store each, successful "
        "or not, with its skill model and demonstration; prints the new ids. On a glove env "
        "(IAS-GloveGrasp-v0) each episode is a glove session (--policy teleop). The "
        "episodes run here, on local worker processes (--workers) or on Ray (--ray); this "
        "process alone writes them, in seed order, with the same content on every backend.",
        formatter_class=HelpFormatter,
    )
    record.add_argument(
        "--env", required=True, metavar="ID", help="e.g. IAS-PenRotate-v0, IAS-GloveGrasp-v0"
    )
    policy_arguments(
        record,
        episodes=1,
        episodes_help="episodes to record",
        policy_help="the grip-transform expert (pen tasks), teleop (glove envs: zero action, "
        "a glove session), uniform random actions, or a saved SB3 model (.zip)",
    )
    db_argument(record, "skill database file, created with its folder if missing")
    env_kwargs_argument(record)
    record.add_argument(
        "--person",
        metavar="ID",
        help="person id stored with the skills: letters, digits, '.', '_', '-' (glove envs: "
        "the simulated person wearing the glove, any id) (default: none stored; on glove envs "
        "the env's person, p1)",
    )
    record.add_argument(
        "--population",
        type=int,
        metavar="N",
        help="glove envs: record --episodes sessions of each of N persons drawn from the "
        "population (instead of --person; docs/population.md) (default: none)",
    )
    record.add_argument(
        "--population-seed",
        type=int,
        default=0,
        metavar="S",
        help="seed of the --population draw: the same seed gives the same persons",
    )
    record.add_argument(
        "--skill",
        metavar="NAME",
        help="glove envs: the skill the person performs after the pinch-lift, one of "
        f"{', '.join(SKILLS)} (stored as the skills' name) (default: none, the pinch-lift)",
    )
    record.add_argument("--no-progress", action="store_true", help="no progress bar")
    parallel_arguments(record)
    record.set_defaults(run=_record)

    merge = commands.add_parser(
        "merge",
        help="join skill databases into one new file",
        description="Copy every skill of the given databases, in their order, into one new "
        "database (new ids; provenance and arrays kept bit for bit). Every array is verified "
        "against its checksum when read; the output is written to a temporary file and "
        "renamed into place when complete, and an existing one is replaced only with "
        "--overwrite.",
        formatter_class=HelpFormatter,
    )
    merge.add_argument("--out", required=True, metavar="PATH", help="the merged database")
    merge.add_argument("dbs", nargs="+", metavar="DB", help="skill databases to join")
    overwrite_argument(merge)
    merge.set_defaults(run=_merge)

    listing = commands.add_parser(
        "list",
        help="list the stored skills",
        description="One line per skill, or with --json one JSON list (id, name, task, "
        "source, is_success, return, length, created) on the last line. Opens the database "
        "read-only: a missing or empty file is an error, nothing is created.",
    )
    db_argument(listing)
    listing.add_argument("--task", metavar="ID", help="only skills of this env id (default: all)")
    listing.add_argument("--success-only", action="store_true", help="only successful skills")
    listing.add_argument("--json", action="store_true", help="print one JSON list")
    listing.set_defaults(run=_list)

    show = commands.add_parser(
        "show",
        help="summarise one skill's model",
        description="Provenance, duration, contact schedule per finger, internal-force "
        "ranges f_int = N^T c and |c_h|, pen excursion. Opens the database read-only and "
        "verifies the skill's checksums.",
    )
    db_argument(show)
    show.add_argument("--id", required=True, type=int, metavar="N", help="skill id (required)")
    show.add_argument("--json", action="store_true", help="print one JSON object")
    show.set_defaults(run=_show)

    export = commands.add_parser(
        "export",
        help="export demonstrations as a dataset (Minari)",
        description="Write the demonstrations of one task as a Minari dataset under "
        "MINARI_DATASETS_PATH (default ~/.minari/datasets); needs the [datasets] extra. "
        "Opens the database read-only and verifies every exported skill's checksums.",
    )
    db_argument(export)
    export.add_argument(
        "--format", choices=("minari",), default="minari", help="dataset format (default: minari)"
    )
    export.add_argument(
        "--dataset-id",
        required=True,
        metavar="ID",
        help="Minari id (namespace/)name-v<version>, e.g. ias/pen-rotate-expert-v0",
    )
    export.add_argument(
        "--task", metavar="ID", help="only skills of this env id (default: the only task there)"
    )
    export.add_argument("--success-only", action="store_true", help="only successful skills")
    export.set_defaults(run=_export)

    pen_skill = commands.add_parser(
        "export-pen-skill",
        help="record the expert executing every human skill on a robot hand, as Minari",
        description="Execute every skill of the shipped human-skill library on "
        "IAS-PenSkill-v0 with the grip-transform expert (Theorem 1 with the skill's grasp "
        "margin) and write the executions as a Minari dataset per hand under "
        "MINARI_DATASETS_PATH: ias/pen-skill/human-v0 on the default hand, "
        "ias/pen-skill-HAND/human-v0 on another; every episode is kept, held or dropped "
        "(its infos say). Needs the [datasets] extra; every dataset id is checked before "
        "any work.",
        formatter_class=HelpFormatter,
    )
    pen_skill.add_argument(
        "--hand", default="all", metavar="NAME|all", help="the robot hand, or every hand"
    )
    pen_skill.add_argument(
        "--episodes-per-skill", type=int, default=1, metavar="N", help="executions per skill"
    )
    pen_skill.add_argument(
        "--skill-ids", metavar="N,N,...", help="only these skills of the library (default: all)"
    )
    pen_skill.add_argument(
        "--dataset-id", metavar="ID", help="the Minari id (one hand only; default: the hand's)"
    )
    pen_skill.add_argument("--db", metavar="PATH", help="also keep them in this new database")
    pen_skill.set_defaults(run=_export_pen_skill)

    check = commands.add_parser(
        "check",
        help="verify every array of every skill against its checksum",
        description="Run SQLite's integrity check, then load every skill read-only and "
        "verify each stored array against its SHA-256 checksum, completeness and "
        "consistency. Prints one line per skill (OK or the problem), or with --json one "
        "JSON object per line ({id, ok, error}). Exit code 0 if all are fine, 2 if any "
        "skill is corrupt (remove it with `skills delete` or restore a backup).",
    )
    db_argument(check)
    check.add_argument("--json", action="store_true", help="one JSON object per skill and line")
    check.set_defaults(run=_check)

    delete = commands.add_parser(
        "delete",
        help="delete one skill (also an incomplete or corrupt one)",
        description="Remove a skill and all its arrays in one transaction. An unknown id "
        "is an error listing the ids there are.",
    )
    db_argument(delete)
    delete.add_argument("--id", required=True, type=int, metavar="N", help="skill id (required)")
    delete.set_defaults(run=_delete)

    migrate = commands.add_parser(
        "migrate",
        help="bring an older database to this schema version and describe its sessions",
        description="Open an existing database for writing, which migrates it: schema "
        "version 1 gets the SHA-256 checksum of every stored array, computed from the "
        "bytes as they are now (read-only commands refuse to load arrays of a version-1 "
        "file until it is migrated); version 3 a column for the person's parameters. "
        "Then every simulated person's glove session recorded with its phases gets what "
        "it lacks: its intended object motion (infos target_height [m], target_tilt "
        "[rad]) and its person's parameters, from the person generator. Nothing stored "
        "is replaced; a session that cannot be described is listed with the reason.",
    )
    db_argument(migrate)
    migrate.set_defaults(run=_migrate)
    add_transfer_command(commands)
    return skills

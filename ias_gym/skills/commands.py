"""The ``ias-gym skills`` command group: record, list, show and export skills.

:func:`add_skills_commands` adds the group to the ``ias-gym`` parser's sub-commands; each
handler takes the parsed arguments and returns an exit code (0 ok, 1 an error whose message
went to stderr). Handlers import what they need when they run, so ``--help`` stays fast.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

#: Exit code of a handled error (bad database, unknown id, bad arguments).
EXIT_ERROR = 1


def _fail(message: str) -> int:
    print(f"error: {message}", file=sys.stderr)
    return EXIT_ERROR


def _expected_errors() -> tuple[type[BaseException], ...]:
    from ias_gym.hardware.can_glove import GloveTimeoutError  # a CAN glove that is silent
    from ias_gym.skills.db import SkillDBError

    return (
        SkillDBError,
        ValueError,
        FileNotFoundError,
        FileExistsError,
        ImportError,
        GloveTimeoutError,
    )


def _record(args: argparse.Namespace) -> int:
    from ias_gym.cli import parse_env_kwargs
    from ias_gym.skills.record import record_skills

    try:
        env_kwargs = parse_env_kwargs(args.env_kwargs)
    except ValueError as exc:
        return _fail(str(exc))

    try:
        ids = record_skills(
            args.env,
            args.policy,
            args.episodes,
            Path(args.db),
            seed=args.seed,
            progress=not args.no_progress,
            env_kwargs=env_kwargs,
            person_id=args.person,
        )
    except _expected_errors() as exc:
        return _fail(str(exc))
    print(f"stored {len(ids)} skills (ids {', '.join(map(str, ids))}) in {args.db}")
    return 0


def _list(args: argparse.Namespace) -> int:
    from ias_gym.skills.db import SkillDB

    success = True if args.success_only else None
    try:
        with SkillDB(args.db) as db:
            skills = db.list_skills(task=args.task, success=success)
    except _expected_errors() as exc:
        return _fail(str(exc))
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

    try:
        with SkillDB(args.db) as db:
            skill = db.get(args.id)
            summary = db.summary(args.id)
    except _expected_errors() as exc:
        return _fail(str(exc))
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

    try:
        path = export_minari(
            args.db, args.dataset_id, task=args.task, success_only=args.success_only
        )
    except _expected_errors() as exc:
        return _fail(str(exc))
    print(f"wrote Minari dataset {args.dataset_id} to {path}")
    return 0


def add_skills_commands(subparsers: argparse._SubParsersAction[Any]) -> argparse.ArgumentParser:
    """Add ``skills`` with its sub-commands ``record``, ``list``, ``show``, ``export``.

    Args:
        subparsers: the object ``parser.add_subparsers(...)`` returned; each leaf parser
            sets ``run`` (``args -> exit code``) as its default.

    Returns:
        The ``skills`` parser.
    """
    from ias_gym.cli import env_kwargs_argument

    skills = subparsers.add_parser(
        "skills",
        help="the skill database: record, list, show and export skills",
        description="Skills (paper sec. 3: contact schedule, object trajectory and the "
        "internal forces of G(t)) with their demonstrations, in an SQLite file.",
    )
    commands = skills.add_subparsers(dest="skills_command", metavar="SUBCOMMAND", required=True)

    def db_argument(p: argparse.ArgumentParser) -> None:
        p.add_argument("--db", required=True, metavar="PATH", help="skill database file")

    record = commands.add_parser(
        "record",
        help="roll out a policy and store every episode as a skill",
        description="Run N seeded episodes (seeds S, S+1, ...) and store each, successful "
        "or not, with its skill model and demonstration; prints the new ids. On a glove env "
        "(IAS-GloveGrasp-v0) each episode is a glove session (--policy teleop).",
    )
    record.add_argument(
        "--env", required=True, metavar="ID", help="e.g. IAS-PenRotate-v0, IAS-GloveGrasp-v0"
    )
    record.add_argument(
        "--policy",
        default="expert",
        metavar="expert|teleop|random|PATH",
        help="the grip-transform expert (pen tasks), teleop (glove envs: zero action, a glove "
        "session), uniform random actions, or a saved SB3 model (.zip)",
    )
    record.add_argument("--episodes", type=int, default=1, metavar="N", help="default 1")
    db_argument(record)
    record.add_argument("--seed", type=int, default=0, metavar="S", help="first seed (0)")
    env_kwargs_argument(record)
    record.add_argument(
        "--person",
        metavar="ID",
        help="person id stored with the skills (glove envs: the env's person, the default; "
        "choose it with --env-kwargs '{\"person_id\": ...}')",
    )
    record.add_argument("--no-progress", action="store_true", help="no progress bar")
    record.set_defaults(run=_record)

    listing = commands.add_parser(
        "list",
        help="list the stored skills",
        description="One line per skill, or with --json one JSON list (id, name, task, "
        "source, is_success, return, length, created) on the last line.",
    )
    db_argument(listing)
    listing.add_argument("--task", metavar="ID", help="only skills of this env id")
    listing.add_argument("--success-only", action="store_true", help="only successful skills")
    listing.add_argument("--json", action="store_true", help="print one JSON list")
    listing.set_defaults(run=_list)

    show = commands.add_parser(
        "show",
        help="summarise one skill's model",
        description="Provenance, duration, contact schedule per finger, internal-force "
        "ranges f_int = N^T c and |c_h|, pen excursion.",
    )
    db_argument(show)
    show.add_argument("--id", required=True, type=int, metavar="N", help="skill id")
    show.add_argument("--json", action="store_true", help="print one JSON object")
    show.set_defaults(run=_show)

    export = commands.add_parser(
        "export",
        help="export demonstrations as a dataset (Minari)",
        description="Write the demonstrations of one task as a Minari dataset under "
        "MINARI_DATASETS_PATH (default ~/.minari/datasets); needs the [datasets] extra.",
    )
    db_argument(export)
    export.add_argument(
        "--format", choices=("minari",), default="minari", help="dataset format (minari)"
    )
    export.add_argument(
        "--dataset-id",
        required=True,
        metavar="ID",
        help="Minari id (namespace/)name-v<version>, e.g. ias/pen-rotate-expert-v0",
    )
    export.add_argument("--task", metavar="ID", help="only skills of this env id")
    export.add_argument("--success-only", action="store_true", help="only successful skills")
    export.set_defaults(run=_export)
    return skills

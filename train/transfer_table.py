"""The skill-transfer table: human glove skills executed by every robot hand, G(t) vs kinematic.

    python train/transfer_table.py --build-db out/pop30.db --population 30 --population-seed S
    python train/transfer_table.py --db out/pop30.db --population 30 --population-seed S \\
        --out-json out/transfer.json --out-md out/transfer.md
    python train/transfer_table.py --figure docs/img/transfer.png

``--build-db`` records glove sessions (``IAS-GloveGrasp-v0``, teleop) of every person and
skill class of the glove-skills library (today's pinch-and-lift where that library is
missing) into a new database, written beside the target and moved there when complete
(the shipped ``ias_gym/assets/human_skills.db`` is made this way). The table runs every
successful glove skill of ``--db`` on every hand with every method (``run_transfer``:
success and its terms held / tracked / margin kept, RMS rotation error [deg], RMS position
error [mm], grasp-margin error [-]) under every class of ``--disturbances`` (the robustness
suite's names) and writes one JSON file (every run and the summaries) and a markdown table,
both atomically. A hand that refuses a skill (``plan_transfer``: its scaled motion within
the person's repeatability of a still pen, or a sliding contact) gets one row per method
and disturbance with ``"success": false`` and ``"refused"``, and no run; the summaries count
them as failures and say how many. ``--heldout`` names the persons never used while
developing (reported separately). ``--weak`` adds, nominal only, the executions the success
test must fail: the grip-transform expert holding the pen still (``weak_still``) or
squeezing to a constant margin of 1.2 or 2.0 (``weak_margin_1.2``, ``weak_margin_2.0``).
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sqlite3
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

#: The weak executions of ``--weak``: name -> how the executed reference is made.
WEAK = ("weak_still", "weak_margin_1.2", "weak_margin_2.0")


def method_gains(method: str, hand: str) -> tuple[str, Any]:
    """``"gt"`` or ``"kinematic"``, or ``"gt:ki=4000"`` (the expert with these
    :class:`~ias_gym.baselines.gains.ControllerGains` fields, the others
    the hand's :func:`~ias_gym.skills.transfer_run.transfer_gains`): the method and its
    gains (``None``: the method's own)."""
    import dataclasses

    from ias_gym.skills.transfer_run import transfer_gains

    name, _, spec = method.partition(":")
    if not spec:
        return name, None
    fields: dict[str, Any] = {k: float(v) for k, v in (item.split("=") for item in spec.split(","))}
    return name, dataclasses.replace(transfer_gains(hand), **fields)


def weak_reference(reference: Any, kind: str) -> Any:
    """The reference a weak execution acts on (it is judged against ``reference``)."""
    from ias_gym.skills.tolerance import constant_margin_reference, still_reference

    if kind == "weak_still":
        return still_reference(reference)
    return constant_margin_reference(reference, float(kind.rsplit("_", 1)[1]))


def skill_classes() -> list[str | None]:
    """The glove skill classes (``None``: the plain pinch-and-lift of the glove env)."""
    try:
        from ias_gym.glove.skills import SKILLS
    except ImportError:
        return [None]
    return list(SKILLS)


def build_db(out: Path, persons: Sequence[str], episodes: int, overwrite: bool) -> None:
    """Record every person's glove sessions of every skill class into a new database."""
    from ias_gym.outputs import atomic_output, check_output_file
    from ias_gym.skills.record import record_skills_spec

    check_output_file(out, overwrite=overwrite, suffixes=(".db",), what="--build-db")
    classes = skill_classes()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "skills.db"
        jobs = [(p, c) for p in persons for c in classes]
        for person, skill in tqdm(jobs, desc="recording", unit="session"):
            kwargs: dict[str, Any] = {"person_id": person}
            if skill is not None:
                kwargs["skill"] = skill
            record_skills_spec(
                "IAS-GloveGrasp-v0",
                "teleop",
                episodes,
                path,
                seed=0,
                progress=False,
                env_kwargs=kwargs,
                person_id=person,
            )
        from ias_gym.skills.db import SkillDB

        with SkillDB(path) as db:  # fold the write-ahead log into the file
            db.list_skills()
        # A rollback journal, not WAL: a WAL file cannot be opened read-only in a directory
        # the reader cannot write (an installed package's assets).
        conn = sqlite3.connect(path)
        conn.execute("PRAGMA journal_mode = DELETE")
        conn.execute("VACUUM")
        conn.close()
        with atomic_output(out, overwrite=overwrite) as final:
            shutil.copyfile(path, final)


def skill_class(summary: Any) -> str:
    """A skill's class: its glove skill name, else the plain pinch-and-lift."""
    return str(summary.env_kwargs.get("skill", "pinch_lift"))


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Success rate and mean errors of a group of runs (errors over all runs)."""

    def mean(key: str) -> float | None:
        values = [r[key] for r in rows if r.get(key) is not None]
        return float(np.mean(values)) if values else None

    def worst(key: str) -> float | None:
        values = [r[key] for r in rows if r.get(key) is not None]
        return float(np.max(values)) if values else None

    ran = [r for r in rows if not r.get("refused")]
    return {
        "runs": len(rows),
        "success_rate": float(np.mean([r["success"] for r in rows])) if rows else math.nan,
        "refused": len(rows) - len(ran),
        "held": int(sum(r["held"] for r in ran)),
        "tracked": int(sum(r["tracked"] for r in ran)),
        "margin_kept": int(sum(r["margin_kept"] for r in ran)),
        "rot_rms_deg": mean("rot_rms_deg"),
        "rot_rms_deg_max": worst("rot_rms_deg"),
        "pos_rms_mm": mean("pos_rms_mm"),
        "margin_err_rel": mean("margin_err_rel"),
        "dropped": int(sum(r["held_s"] < r["duration_s"] - 1e-6 for r in ran)),
    }


def fmt(value: float | None, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def markdown(summary: dict[str, Any], heldout: Sequence[str]) -> str:
    """The table: per hand, method and skill class, then all classes, then held-out people."""
    lines = [
        "| hand | method | disturbance | skills | runs | success | held / tracked / margin "
        "kept | rot RMS [deg] mean / max | pos RMS [mm] | margin error | dropped | refused |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for key, s in summary.items():
        hand, method, disturbance, group = key.split("|")
        lines.append(
            f"| {hand} | {method} | {disturbance} | {group} | {s['runs']} | "
            f"{100 * s['success_rate']:.0f} % | {s['held']} / {s['tracked']} / "
            f"{s['margin_kept']} | "
            f"{fmt(s['rot_rms_deg'], '.2f')} / {fmt(s['rot_rms_deg_max'], '.2f')} | "
            f"{fmt(s['pos_rms_mm'], '.2f')} | "
            f"{fmt(None if s['margin_err_rel'] is None else 100 * s['margin_err_rel'], '.1f')} % | "
            f"{s['dropped']} | {s.get('refused', 0)} |"
        )
    note = f"\nHeld-out persons (never used while developing): {', '.join(heldout)}.\n"
    return "\n".join(lines) + "\n" + (note if heldout else "")


def main(argv: Sequence[str] | None = None) -> int:
    """Build the database or run the table."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--build-db", metavar="FILE.db", help="record a new human-skill DB")
    parser.add_argument(
        "--persons", metavar="ID,ID,...", help="persons (--build-db; or --population)"
    )
    parser.add_argument(
        "--population",
        type=int,
        metavar="N",
        help="instead of --persons and --heldout: N persons drawn with --population-seed, "
        "all of them held out",
    )
    parser.add_argument("--population-seed", type=int, default=0, help="seed of --population")
    parser.add_argument("--episodes", type=int, default=1, help="sessions per person and skill")
    parser.add_argument("--db", help="the skill database (default: the shipped human skills)")
    parser.add_argument("--hands", default="all", help="comma-separated hands, or all")
    parser.add_argument("--methods", default="gt,kinematic", help="comma-separated methods")
    parser.add_argument(
        "--disturbances", default="nominal", help="comma-separated robustness classes"
    )
    parser.add_argument("--weak", action="store_true", help="add the weak executions (nominal)")
    parser.add_argument(
        "--merge",
        nargs="+",
        metavar="FILE.json",
        help="instead of running: one table of the runs of these --out-json files (e.g. "
        "two processes' shares of the hands)",
    )
    parser.add_argument(
        "--heldout", default="", metavar="ID,ID,...", help="persons never used in development"
    )
    parser.add_argument("--seed", type=int, default=0, help="reset seed of every run")
    parser.add_argument("--duration", type=float, default=3.0, help="episode length [s]")
    parser.add_argument("--out-json", help="JSON of every run and the summaries")
    parser.add_argument("--out-md", help="the markdown table")
    parser.add_argument("--overwrite", action="store_true", help="replace existing outputs")
    parser.add_argument("--figure", metavar="FILE.png", help="draw the transfer figure only")
    parser.add_argument("--figure-id", type=int, default=2, help="the figure's skill id")
    args = parser.parse_args(argv)
    if args.population is not None:
        from ias_gym.glove.population import population_ids

        drawn = population_ids(args.population, args.population_seed)
        args.persons = args.heldout = ",".join(drawn)
    if args.figure:
        from ias_gym.figures.transfer_figure import transfer_figure

        transfer_figure(args.figure, args.db, args.figure_id, overwrite=args.overwrite)
        print(f"wrote {args.figure}")
        return 0

    from ias_gym.outputs import check_output_file

    if args.build_db:
        if not args.persons:
            parser.error("--build-db needs --persons ID,ID,... or --population N")
        build_db(Path(args.build_db), args.persons.split(","), args.episodes, args.overwrite)
        print(f"wrote {args.build_db}")
        return 0
    outputs = [Path(p) for p in (args.out_json, args.out_md) if p]
    for path in outputs:
        check_output_file(path, overwrite=args.overwrite)
    from ias_gym.robustness import check_classes

    disturbances = check_classes(args.disturbances.split(","))
    if args.merge:
        parts = [json.loads(Path(p).read_text()) for p in args.merge]
        merged_rows = [r for part in parts for r in part["runs"]]
        keys = ("hands", "methods", "disturbances")
        merged = {k: list(dict.fromkeys(x for part in parts for x in part[k])) for k in keys}
        return write_table(args, merged_rows, parts[0]["db"], parts[0]["heldout"], **merged)

    from ias_gym.skills.db import SkillDB
    from ias_gym.skills.transfer import shipped_skill_db
    from ias_gym.skills.transfer_plan import plan_transfer
    from ias_gym.skills.transfer_run import run_transfer
    from ias_gym.skills.workspace import hand_names

    db_path = Path(args.db) if args.db else shipped_skill_db()
    hands = hand_names() if args.hands == "all" else args.hands.split(",")
    methods = args.methods.split(",")
    heldout = [p for p in args.heldout.split(",") if p]
    with SkillDB(db_path, readonly=True) as db:
        summaries = [s for s in db.list_skills(success=True) if s.person_id]
        skills = [(s, db.get(s.id)) for s in summaries]
    from ias_gym.robustness import DISTURBANCES

    rows: list[dict[str, Any]] = []
    jobs = [(s, h, m, d) for s, _ in skills for h in hands for m in methods for d in disturbances]
    if args.weak:
        jobs += [(s, h, w, "nominal") for s, _ in skills for h in hands for w in WEAK]
    plans = {
        (summary.id, hand): plan_transfer(skill, hand, duration=args.duration)
        for summary, skill in tqdm(skills, desc="plan", unit="skill")
        for hand in hands
    }
    for summary, hand, method, disturbance in tqdm(jobs, desc="transfer", unit="run"):
        plan = plans[(summary.id, hand)]
        if plan.refused is not None:  # a failure, with its reason and no run
            rows.append(
                {
                    **plan.refusal_row(),
                    "method": method,
                    "disturbance": disturbance,
                    "skill_class": skill_class(summary),
                    "heldout": summary.person_id in heldout,
                    "duration_s": args.duration,
                }
            )
            continue
        reference = plan.reference
        weak = method in WEAK
        name, gains = ("gt", None) if weak else method_gains(method, hand)
        run, _ = run_transfer(
            reference,
            hand,
            name,
            gains=gains,
            seed=args.seed,
            duration=args.duration,
            executed=weak_reference(reference, method) if weak else None,
            **DISTURBANCES[disturbance],
        )
        row = run.to_json()
        row.update(
            refused=None,
            executed_mm=plan.executed_mm,
            executed_deg=plan.executed_deg,
            method=method,
            disturbance=disturbance,
            skill_class=skill_class(summary),
            heldout=summary.person_id in heldout,
            duration_s=args.duration,
        )
        rows.append(row)
    all_methods = methods + (list(WEAK) if args.weak else [])
    return write_table(args, rows, str(db_path), heldout, hands, all_methods, disturbances)


def write_table(
    args: argparse.Namespace,
    rows: list[dict[str, Any]],
    db: str,
    heldout: list[str],
    hands: list[str],
    methods: list[str],
    disturbances: list[str],
) -> int:
    """Summarise the runs, print the table and write the outputs."""
    from ias_gym.outputs import atomic_output

    groups: dict[str, list[dict[str, Any]]] = {}
    for row in rows:
        for group in (row["skill_class"], "all", "held-out" if row["heldout"] else None):
            if group is not None:
                key = f"{row['hand']}|{row['method']}|{row['disturbance']}|{group}"
                groups.setdefault(key, []).append(row)
    summary = {key: summarise(group) for key, group in sorted(groups.items())}
    table = markdown(summary, heldout)
    print(table)
    persons = sorted({r["person"] for r in rows})
    result = {
        "db": db,
        "persons": persons,
        "heldout": heldout,
        "hands": hands,
        "methods": methods,
        "disturbances": disturbances,
        "summary": summary,
        "runs": rows,
    }
    if args.out_json:
        with atomic_output(args.out_json, overwrite=args.overwrite) as tmp:
            tmp.write_text(json.dumps(result, indent=1, allow_nan=False))
    if args.out_md:
        with atomic_output(args.out_md, overwrite=args.overwrite) as tmp:
            tmp.write_text(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())

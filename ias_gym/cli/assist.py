"""``ias-gym assist``: the assisted glove world (issue #14, paper Flow 3).

- ``assist evaluate``: success of the skills with and without the analytic assistant per
  operator impairment (``IAS-GloveAssist-v0``), with ``--json`` one JSON object on the last
  line (the recognition metrics ``recog_acc_at_33``, ``recog_acc_at_60``,
  ``time_to_recognise_s``, ``false_trigger_rate``, ``unknown_auroc`` and ``by_impairment``:
  impairment -> ``success_unassisted``, ``success_assisted``, ``intervention``);
- ``assist demo``: a video of an assisted session beside the same session unassisted.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from ias_gym.cli.args import HelpFormatter, non_negative_int, positive_int
from ias_gym.errors import InputError

#: The recognition metrics of ``assist evaluate --json`` (filled by the recogniser's
#: metrics when that module is present, else null).
RECOGNITION_KEYS = (
    "recog_acc_at_33",
    "recog_acc_at_60",
    "time_to_recognise_s",
    "false_trigger_rate",
    "unknown_auroc",
)


def _persons(text: str) -> list[str]:
    from ias_gym.glove.ids import check_id

    persons = [p.strip() for p in text.split(",") if p.strip()]
    if not persons:
        raise InputError("--persons needs at least one person id, e.g. p7,p8,p9")
    return [check_id(p, "--persons") for p in persons]


def _impairments(text: str) -> list[str]:
    from ias_gym.assist.impairments import IMPAIRMENTS

    if text == "all":
        return list(IMPAIRMENTS)
    names = [n.strip() for n in text.split(",") if n.strip()]
    for name in names:
        if name not in IMPAIRMENTS:
            raise InputError(
                f"--impairment {name!r} is not known; choose from {', '.join(IMPAIRMENTS)} or all"
            )
    return names


def _recognition_metrics(db: Path, persons: list[str], seed: int) -> dict[str, Any]:
    """The recogniser's metrics on these persons' sessions, or nulls without a recogniser."""
    try:
        from ias_gym.assist import recognition  # type: ignore[attr-defined]
    except ImportError:
        return dict.fromkeys(RECOGNITION_KEYS)
    metrics = getattr(recognition, "recognition_metrics", None)
    if metrics is None:
        return dict.fromkeys(RECOGNITION_KEYS)
    result = metrics(db=db, persons=persons, seed=seed)
    return {
        k: result.get(k) if isinstance(result, dict) else getattr(result, k, None)
        for k in RECOGNITION_KEYS
    }


def _evaluate(args: argparse.Namespace) -> int:
    persons = _persons(args.persons)
    impairments = _impairments(args.impairment)
    db = Path(args.db)
    if not db.is_file():
        raise InputError(f"--db {db} does not exist; give a skill library (skills record)")
    from tqdm import tqdm

    from ias_gym.assist.assistants import AnalyticAssistant, load_templates
    from ias_gym.assist.evaluation import evaluate_assistance

    templates = load_templates(db)
    total = len(persons) * len(impairments) * args.episodes
    with tqdm(total=total, desc="sessions", disable=args.json, file=sys.stderr) as bar:
        scores = evaluate_assistance(
            lambda: AnalyticAssistant(templates),
            persons,
            impairments,
            args.episodes,
            args.seed,
            progress=lambda: bar.update(1),
        )
    if args.json:
        out = _recognition_metrics(db, persons, args.seed)
        out["by_impairment"] = {k: v.to_json() for k, v in scores.items()}
        print(json.dumps(out))
    else:
        for name, s in scores.items():
            print(
                f"{name}: success {100 * s.success_unassisted:.0f} % unassisted, "
                f"{100 * s.success_assisted:.0f} % assisted, intervention "
                f"{s.intervention:.3f} ({s.sessions} sessions)"
            )
    return 0


def _demo(args: argparse.Namespace) -> int:
    from ias_gym.evaluation import VIDEO_SUFFIXES
    from ias_gym.outputs import check_output_file

    video = check_output_file(
        args.video, overwrite=args.overwrite, suffixes=VIDEO_SUFFIXES, what="--video"
    )
    import gymnasium as gym
    import numpy as np

    from ias_gym.assist.assistants import AnalyticAssistant, load_templates
    from ias_gym.evaluation import write_video

    templates = load_templates(args.db)
    runs: list[list[Any]] = []
    for assisted in (False, True):
        env = gym.make(
            "IAS-GloveAssist-v0",
            person_id=args.person,
            skill=args.skill,
            impairment=args.impairment,
            render_mode="rgb_array",
        )
        u: Any = env.unwrapped
        env.reset(seed=args.seed)
        assistant = AnalyticAssistant(templates) if assisted else None
        if assistant is not None:
            assistant.reset(u)
        frames: list[Any] = [env.render()]
        done = False
        while not done:
            action = assistant.act(u) if assistant is not None else np.zeros(10)
            _, _, terminated, truncated, _ = env.step(action)
            frames.append(env.render())
            done = bool(terminated or truncated)
        env.close()
        runs.append(frames)
    n = max(len(r) for r in runs)
    # the shorter session (a dropped pen ends it) holds its last frame
    side = [np.hstack([r[min(i, len(r) - 1)] for r in runs]) for i in range(0, n, 2)]
    write_video(video, side, fps=50.0, overwrite=args.overwrite)
    print(f"wrote {video}: left unassisted, right assisted ({args.impairment}, {args.skill})")
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
        "impairment, without and with the analytic assistant, and judge them against the "
        "unimpaired person's session (docs/assistance.md). With --json the last line is "
        "one object: " + ", ".join(RECOGNITION_KEYS) + " and by_impairment.",
        formatter_class=HelpFormatter,
    )
    p.add_argument("--db", required=True, metavar="F", help="the skill library (SQLite)")
    p.add_argument("--persons", default="p7,p8,p9", metavar="ID,ID,...", help="person ids")
    p.add_argument(
        "--impairment",
        default="all",
        metavar="NAME|none|all",
        help="impairment(s), comma-separated",
    )
    p.add_argument(
        "--episodes", type=positive_int, default=6, metavar="N", help="sessions per person"
    )
    p.add_argument("--seed", type=non_negative_int, default=0, metavar="S", help="first seed")
    p.add_argument("--json", action="store_true", help="one JSON object on the last line")
    p.set_defaults(run=_evaluate)
    return p


def add_assist_demo(commands: argparse._SubParsersAction[Any]) -> argparse.ArgumentParser:
    """Add ``assist demo`` to the ``assist`` sub-commands.

    Args:
        commands: the ``assist`` group's sub-parsers.

    Returns:
        The parser.
    """
    p = commands.add_parser(
        "demo",
        help="video: an assisted session beside the same session unassisted",
        description="Render one IAS-GloveAssist-v0 session without (left) and with (right) "
        "the analytic assistant, side by side, into an MP4.",
        formatter_class=HelpFormatter,
    )
    p.add_argument("--video", required=True, metavar="FILE", help="the MP4 to write")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --video")
    p.add_argument("--db", default=None, metavar="F", help="skill library (default: shipped)")
    p.add_argument("--person", default="p1", metavar="ID", help="the operator")
    p.add_argument("--skill", default="seesaw_slow", metavar="NAME", help="the skill")
    p.add_argument("--impairment", default="weak_grip", metavar="NAME", help="the impairment")
    p.add_argument("--seed", type=non_negative_int, default=0, metavar="S", help="reset seed")
    p.set_defaults(run=_demo)
    return p


def add_assist_commands(commands: argparse._SubParsersAction[Any]) -> argparse.ArgumentParser:
    """Add the ``assist`` group (``evaluate``, ``demo``) to ``ias-gym``.

    Args:
        commands: the top-level sub-parsers.

    Returns:
        The group's parser.
    """
    group = commands.add_parser(
        "assist",
        help="the assisted glove world (IAS-GloveAssist-v0)",
        description="Recognise and assist the glove operator's skills (paper Flow 3).",
        formatter_class=HelpFormatter,
    )
    sub = group.add_subparsers(dest="assist_command", metavar="COMMAND", required=True)
    add_assist_evaluate(sub)
    add_assist_demo(sub)
    return group

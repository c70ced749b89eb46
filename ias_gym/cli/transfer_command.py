"""``ias-gym skills transfer``: execute a stored (human) skill on robot hands of other kinematics.

The skill's object trajectory relative to its grasp frame, scaled into each hand's
workspace, and its grasp margin (:mod:`ias_gym.skills.transfer`) are executed by the
grip-transform expert (``--method gt``: Theorem 1), the kinematic baseline
(``--method kinematic``) or the retargeting baseline (``--method retarget``: dex-retargeting
and joint position control, ``pip install 'ias-gym[retarget]'``), nominal or under a class of
the robustness suite (``--disturbance``); prints the transfer metrics per hand, with
``--json`` one JSON object per hand and line (``hand``, ``method``, ``success``, ``rot_rms_deg``,
``pos_rms_mm``, ``margin_err_rel``, ``scale``, the per-axis excursions
``demonstrated_mm`` / ``executed_mm`` and ``demonstrated_deg`` / ``executed_deg``, and
``fingers``: which demonstrated contact each finger stands in for, with its margin).
``--list-hands`` lists the hands. A demonstration whose own episode failed is refused unless
``--allow-failed``. A hand that cannot execute the skill refuses it
(:func:`ias_gym.skills.transfer_plan.plan_transfer`: its motion, scaled into the hand,
would not differ from a still pen by more than the person repeats it, or the skill slides a
contact): with one ``--hand`` that is a one-line error, with ``--hand all`` the hand's line
says ``"success": false, "refused": "<why>"`` and the other hands run.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from ias_gym.cli.args import HelpFormatter, non_negative_int
from ias_gym.errors import InputError


def _duration(text: str) -> float:
    """argparse type: an episode length in (0, 60] s."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, got {text!r}") from None
    if not 0 < value <= 60:  # False for NaN too
        raise argparse.ArgumentTypeError(f"must be in (0, 60] s, got {value}")
    return value


def _list_hands() -> int:
    from ias_gym.skills.workspace import hand_names, hand_workspace

    for name in hand_names():
        ws = hand_workspace(name)
        reach = "; ".join(
            f"at {math.degrees(share * ws.tilt):.1f} deg it {ws.describe_reach(share * ws.tilt)}"
            for share in ws.tilt_shares
        )
        print(f"{name}: {ws.describe_motion()}; {reach} (diagonals: HandSpec.reach_by_tilt)")
    return 0


def _axes(values: dict[str, float]) -> str:
    """``1.2/3.4/0.5``: a plan's per-axis excursions, one decimal."""
    return "/".join(f"{v:.1f}" for v in values.values())


def _transfer(args: argparse.Namespace) -> int:
    if args.list_hands:
        return _list_hands()
    if args.id is None:
        raise InputError("skills transfer needs --id N (or --list-hands)")
    from ias_gym.outputs import check_output_file
    from ias_gym.skills.db import SkillDB, SkillNotFoundError
    from ias_gym.skills.transfer import shipped_skill_db
    from ias_gym.skills.transfer_plan import plan_transfer
    from ias_gym.skills.transfer_run import METHODS, run_transfer
    from ias_gym.skills.workspace import hand_names

    if args.method not in METHODS:
        raise InputError(f"unknown --method {args.method!r}; methods: {list(METHODS)}")
    if args.method == "retarget":  # before any work
        from ias_gym.baselines.retarget import require_retargeting

        require_retargeting()
    from ias_gym.robustness import DISTURBANCES

    if args.disturbance not in DISTURBANCES:
        raise InputError(
            f"unknown --disturbance {args.disturbance!r}; classes: {', '.join(DISTURBANCES)}"
        )
    disturbance = DISTURBANCES[args.disturbance]
    hands = hand_names() if args.hand == "all" else [args.hand]
    unknown = [h for h in hands if h not in hand_names()]
    if unknown:
        raise InputError(f"unknown --hand {unknown[0]!r}; hands: {hand_names()} or all")
    video: Path | None = None
    if args.video is not None:  # before any work
        from ias_gym.evaluation import VIDEO_SUFFIXES

        video = check_output_file(
            args.video, overwrite=args.overwrite, suffixes=VIDEO_SUFFIXES, what="--video"
        )
    db_path = Path(args.db) if args.db is not None else shipped_skill_db()
    if not db_path.is_file():
        raise InputError(
            f"--db {db_path} does not exist; record skills with `ias-gym skills record`"
        )
    with SkillDB(db_path, readonly=True) as db:
        try:
            skill = db.get(args.id)
        except SkillNotFoundError as exc:
            raise InputError(str(exc)) from exc
    if not skill.is_success and not args.allow_failed:
        raise InputError(
            f"skill {args.id} in {db_path} is a failed demonstration (its episode did not "
            "succeed); transfer it anyway with --allow-failed"
        )
    frames_all: list[Any] = []
    for hand in hands:
        plan = plan_transfer(skill, hand, duration=args.duration)
        if plan.refused is not None:
            if args.hand != "all":
                hint = "; another hand may take it (--list-hands)" if plan.too_small else ""
                raise InputError(f"{plan.refused}{hint}")
            if args.json:
                row = {**plan.refusal_row(), "method": args.method}
                print(json.dumps({**row, "disturbance": args.disturbance}))
            else:
                print(f"{hand} {args.method}: REFUSED ({plan.refused})")
            sys.stdout.flush()
            continue
        run, frames = run_transfer(
            plan.reference,
            hand,
            args.method,
            seed=args.seed,
            render=video is not None,
            duration=args.duration,
            **disturbance,
        )
        frames_all += frames
        if args.json:
            print(json.dumps({**run.to_json(), "disturbance": args.disturbance, **plan.to_json()}))
        else:
            failed = [k for k in ("held", "tracked", "margin_kept") if not getattr(run, k)]
            verdict = "success" if run.success else f"FAILED (not {', '.join(failed)})"
            print(
                f"{hand} {args.method}: {verdict}, rotation RMS "
                f"{run.rot_rms_deg:.2f} deg, position RMS {run.pos_rms_mm:.2f} mm, margin "
                f"error {100 * run.margin_err_rel:.1f} %, scale {run.scale:.3f} "
                f"(rotation {run.scale_rotation:.3f}), held {run.held_s:.2f} s; largest "
                f"excursion x/y/z {_axes(plan.executed_mm)} of {_axes(plan.demonstrated_mm)} "
                f"mm, tilt/turn {_axes(plan.executed_deg)} of {_axes(plan.demonstrated_deg)} deg"
            )
        sys.stdout.flush()
    if video is not None:
        from ias_gym.evaluation import write_video

        write_video(video, frames_all, fps=50.0, overwrite=args.overwrite)
    return 0


def add_transfer_command(commands: argparse._SubParsersAction[Any]) -> argparse.ArgumentParser:
    """Add ``transfer`` to the ``skills`` sub-commands.

    Args:
        commands: the ``skills`` group's sub-parsers.

    Returns:
        The ``transfer`` parser.
    """
    transfer = commands.add_parser(
        "transfer",
        formatter_class=HelpFormatter,
        help="execute a stored skill on robot hands (grip transform, kinematic or retargeting)",
        description="Turn a stored skill (e.g. a glove session) into a reference for each "
        "robot hand - the object's motion relative to its grasp frame, scaled into the "
        "hand's workspace, and the person's grasp margin - and execute it with the "
        "grip-transform expert (gt, Theorem 1), the kinematic baseline or the retargeting "
        "baseline (retarget: dex-retargeting and joint position control, the retarget "
        "extra), nominal or under a disturbance class. Success: the pen held, the motion "
        "tracked and the margin kept within the tolerances of the person's own "
        "repeatability. A hand whose scaled motion could not be told from a still pen by "
        "the person's own repeatability, or that would have to slide a finger, refuses the "
        "skill (an error with one --hand; with --hand all its line says why and the others "
        "run). Prints the transfer metrics per hand; with --json one JSON object "
        "per hand and line (hand, "
        "method, disturbance, success, refused, held, tracked, margin_kept, rot_rms_deg, "
        "pos_rms_mm, margin_err_rel, tolerance, scale, scale_rot, demonstrated_mm, "
        "executed_mm, demonstrated_deg, executed_deg, fingers, held_s, skill_id, "
        "person, skill).",
    )
    transfer.add_argument(
        "--db",
        metavar="PATH",
        help="an existing skill database (default: the human skills shipped with the package)",
    )
    transfer.add_argument("--id", type=int, metavar="N", help="the skill's id")
    transfer.add_argument(
        "--hand", default="ias4f", metavar="NAME|all", help="the robot hand, or all hands"
    )
    transfer.add_argument(
        "--method",
        default="gt",
        metavar="gt|kinematic|retarget",
        help="how the hand executes it (retarget: pip install 'ias-gym[retarget]')",
    )
    transfer.add_argument(
        "--seed", type=non_negative_int, default=0, metavar="S", help="the reset seed"
    )
    transfer.add_argument(
        "--duration", type=_duration, default=3.0, metavar="SECONDS", help="episode length [s]"
    )
    transfer.add_argument(
        "--disturbance",
        default="nominal",
        metavar="CLASS",
        help="a class of the robustness suite (`ias-gym robustness`), e.g. friction_x0.7, "
        "mass_x1.3, push_0.3N_50ms",
    )
    transfer.add_argument(
        "--allow-failed",
        action="store_true",
        help="transfer a demonstration whose own episode failed (refused by default)",
    )
    transfer.add_argument("--video", metavar="FILE", help="an MP4 of the executions")
    transfer.add_argument("--overwrite", action="store_true", help="replace an existing --video")
    transfer.add_argument("--json", action="store_true", help="one JSON object per hand and line")
    transfer.add_argument("--list-hands", action="store_true", help="list the hands and exit")
    transfer.set_defaults(run=_transfer)
    return transfer

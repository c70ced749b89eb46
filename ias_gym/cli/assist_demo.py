"""``ias-gym assist demo``, and what it shares with ``assist evaluate``: which assistant
(:func:`assistant_factory`), and the ``--assistant`` and ``--operator`` arguments.

``assist demo`` writes a video of an assisted session beside the same session unassisted.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ias_gym.cli.args import HelpFormatter, non_negative_int
from ias_gym.errors import InputError
from ias_gym.glove.operator import OPERATORS

#: The recogniser the assistant uses in ``assist evaluate`` (the better one on the
#: recognition table).
ASSIST_METHOD = "phase"


def _recogniser_factory(method: str, db: Path | None) -> Any:
    """``() -> recogniser`` for the assistant: ``oracle`` (None: the assistant's oracle on
    the env's true intent) or a recogniser of :mod:`ias_gym.assist.recognition` built once
    on ``db`` (default: the shipped library) and reset by the assistant every session."""
    if method == "oracle":
        return lambda: None
    from ias_gym.assist.recogniser_registry import METHODS, make_recogniser
    from ias_gym.skills import SkillDB
    from ias_gym.skills.transfer import shipped_skill_db

    if method not in METHODS:
        raise InputError(f"--recogniser {method!r}: choose oracle or one of {', '.join(METHODS)}")
    with SkillDB(db if db is not None else shipped_skill_db(), readonly=True) as handle:
        recogniser = make_recogniser(method, handle)
    return lambda: recogniser


def assistant_factory(kind: str, recogniser: str, db: Path | None) -> Any:
    """``() -> assistant``: the observation assistant
    (:func:`~ias_gym.assist.policy.make_assistant`, recogniser ``phase``, ``dtw`` or
    ``none``) or the analytic one on the env's state."""
    if kind == "observation":
        from ias_gym.assist.policy import RECOGNISERS, make_assistant
        from ias_gym.envs.glove_assist import OBSERVATION_PARTS
        from ias_gym.envs.layout import observation_layout

        if recogniser not in RECOGNISERS:
            raise InputError(
                f"--recogniser {recogniser!r}: the observation assistant takes one of "
                f"{', '.join(RECOGNISERS)}"
            )
        layout = observation_layout(OBSERVATION_PARTS)
        assistant = make_assistant(db, recogniser, layout=layout)
        return lambda: assistant
    from ias_gym.assist.assistants import AnalyticAssistant
    from ias_gym.assist.skill_templates import load_templates

    templates = load_templates(db)
    make_recogniser = _recogniser_factory(recogniser, db)
    return lambda: AnalyticAssistant(templates, make_recogniser())


def add_operator_argument(p: argparse.ArgumentParser) -> None:
    """Add ``--operator`` (the simulated person, :data:`~ias_gym.glove.operator.OPERATORS`)."""
    p.add_argument(
        "--operator",
        default="closed_loop",
        choices=OPERATORS,
        help="the simulated person: in the loop (grips by touch, corrects by sight) or the "
        "open-loop script",
    )


def add_assistant_argument(p: argparse.ArgumentParser, default: str) -> None:
    """Add ``--assistant`` (``observation`` or ``analytic``, ``default`` if not given)."""
    p.add_argument(
        "--assistant",
        default=default,
        choices=("observation", "analytic"),
        help="observation: the policy on observations that completes a stopped skill; "
        "analytic: the assistant that reads the env's state (tremor, bias, weak grip)",
    )


def _duration(text: str) -> float:
    """A session length in (0, 10] s."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number of seconds, got {text!r}") from None
    if not 0.0 < value <= 10.0:
        raise argparse.ArgumentTypeError(f"must be in (0, 10] s, got {text}")
    return value


def _label(frame: Any, text: str) -> Any:
    """``frame`` (H, W, 3) with ``text`` written in its top left corner."""
    import numpy as np
    from PIL import Image, ImageDraw  # pillow: matplotlib's dependency

    image = Image.fromarray(np.ascontiguousarray(frame))
    draw = ImageDraw.Draw(image)
    draw.rectangle((0, 0, 8 + 7 * len(text), 22), fill=(255, 255, 255))
    draw.text((4, 5), text, fill=(0, 0, 0))
    return np.asarray(image)


def _demo(args: argparse.Namespace) -> int:
    from ias_gym.evaluation import VIDEO_SUFFIXES
    from ias_gym.outputs import check_output_file

    video = check_output_file(
        args.video, overwrite=args.overwrite, suffixes=VIDEO_SUFFIXES, what="--video"
    )
    import gymnasium as gym
    import numpy as np

    from ias_gym.assist.sessions import AssistantPolicy
    from ias_gym.evaluation import write_video
    from ias_gym.rollout import FrameRecorder, rollout

    make = assistant_factory(args.assistant, args.recogniser, Path(args.db) if args.db else None)
    runs: list[list[Any]] = []
    for assisted in (False, True):
        env = gym.make(
            "IAS-GloveAssist-v0",
            person_id=args.person,
            skill=args.skill,
            impairment=args.impairment,
            duration=args.duration,
            operator=args.operator,
            render_mode="rgb_array",
        )
        u: Any = env.unwrapped
        frames = FrameRecorder()  # the reset and every step
        policy = AssistantPolicy(env, make() if assisted else None)
        rollout(
            env,
            policy,
            args.seed,
            keep_observations=False,
            keep_infos=False,
            on_reset=frames.on_reset,
            on_step=frames.on_step,
        )
        env.close()
        runs.append(frames.frames)
    n = max(len(r) for r in runs)
    # the shorter session (a dropped pen ends it) holds its last frame
    names = (f"unassisted ({args.impairment})", f"assisted ({args.impairment})")
    side = [
        np.hstack(
            [
                _label(r[min(i, len(r) - 1)], f"{name}  t = {min(i, len(r) - 1) * u.dt:.2f} s")
                for r, name in zip(runs, names, strict=True)
            ]
        )
        for i in range(0, n, 2)
    ]
    write_video(video, side, fps=50.0, overwrite=args.overwrite)
    print(f"wrote {video}: left unassisted, right assisted ({args.impairment}, {args.skill})")
    return 0


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
        "an assistant, side by side, into an MP4 (a stopped skill: --impairment stops:at=0.4 "
        "--assistant observation).",
        formatter_class=HelpFormatter,
    )
    p.add_argument("--video", required=True, metavar="FILE", help="the MP4 to write")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --video")
    p.add_argument("--db", default=None, metavar="F", help="skill library (default: shipped)")
    p.add_argument("--person", default="p1", metavar="ID", help="the operator")
    p.add_argument("--skill", default="seesaw_slow", metavar="NAME", help="the skill")
    p.add_argument(
        "--impairment", default="biased_calibration", metavar="NAME", help="the impairment"
    )
    p.add_argument("--seed", type=non_negative_int, default=0, metavar="S", help="reset seed")
    p.add_argument(
        "--duration", type=_duration, default=4.0, metavar="S", help="session length [s]"
    )
    add_assistant_argument(p, "analytic")
    add_operator_argument(p)
    p.add_argument(
        "--recogniser",
        default=ASSIST_METHOD,
        metavar="oracle|dtw|phase|none",
        help="intent source (oracle: the analytic assistant only; none: the observation "
        "assistant without skill knowledge)",
    )
    p.set_defaults(run=_demo)
    return p

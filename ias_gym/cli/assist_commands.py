"""``ias-gym assist ...``: intent recognition and assistance of glove sessions.

``assist recognise`` builds the recognisers on the glove sessions of a skill database,
records sessions of held-out persons and reports accuracy over the observed fraction of the
skill's motion, time to recognise, false triggers and the unknown-skill AUROC
(:mod:`ias_gym.assist.metrics`). The library is imported when the command runs.

``assist evaluate`` runs ``IAS-GloveAssist-v0`` sessions with and without the analytic
assistant per operator impairment; with ``--json`` the last line is one object with the
recognition keys (the recogniser the assistant uses, :data:`ASSIST_METHOD`, on the same
persons; null when they are in the library) and ``by_impairment``: impairment ->
``success_unassisted``, ``success_assisted``, ``intervention``. ``assist demo`` writes a
video of an assisted session beside the same session unassisted.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from ias_gym.cli.args import HelpFormatter, episode_arguments, int_at_least, non_negative_int
from ias_gym.errors import InputError

#: The recognition keys of ``assist recognise --json`` (per method).
RECOGNITION_KEYS = (
    "recog_acc_at_33",
    "recog_acc_at_60",
    "time_to_recognise_s",
    "false_trigger_rate",
    "unknown_auroc",
)
#: The recogniser the assistant uses in ``assist evaluate`` (the better one on the
#: recognition table).
ASSIST_METHOD = "phase"


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


def _assistant_factory(kind: str, recogniser: str, db: Path | None) -> Any:
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


def _evaluate(args: argparse.Namespace) -> int:
    persons = _persons_of(args, EVALUATION_POPULATION)
    impairments = _impairments(args.impairment)
    db = Path(args.db)
    if not db.is_file():
        raise InputError(f"--db {db} does not exist; give a skill library (skills record)")
    from tqdm import tqdm

    from ias_gym.assist.assistance_evaluation import evaluate_assistance

    make = _assistant_factory(args.assistant, args.recogniser, db)
    total = len(persons) * len(impairments) * args.episodes
    with tqdm(total=total, desc="sessions", disable=args.json, file=sys.stderr) as bar:
        scores = evaluate_assistance(
            make,
            persons,
            impairments,
            args.episodes,
            args.seed,
            progress=lambda: bar.update(1),
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

    make = _assistant_factory(args.assistant, args.recogniser, Path(args.db) if args.db else None)
    runs: list[list[Any]] = []
    for assisted in (False, True):
        env = gym.make(
            "IAS-GloveAssist-v0",
            person_id=args.person,
            skill=args.skill,
            impairment=args.impairment,
            duration=args.duration,
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


def _add_assistant_argument(p: argparse.ArgumentParser, default: str) -> None:
    p.add_argument(
        "--assistant",
        default=default,
        choices=("observation", "analytic"),
        help="observation: the policy on observations that completes a stopped skill; "
        "analytic: the assistant that reads the env's state (tremor, bias, weak grip)",
    )


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
    _add_assistant_argument(p, "observation")
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
    _add_assistant_argument(p, "analytic")
    p.add_argument(
        "--recogniser",
        default=ASSIST_METHOD,
        metavar="oracle|dtw|phase|none",
        help="intent source (oracle: the analytic assistant only; none: the observation "
        "assistant without skill knowledge)",
    )
    p.set_defaults(run=_demo)
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
    add_assist_evaluate(commands)
    add_assist_demo(commands)

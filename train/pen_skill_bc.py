"""An SB3 agent across human skills: BC or DAgger from the expert, then PPO fine-tuning.

    python train/pen_skill_bc.py --hand ias4f --n-demos 200 --train-persons 20 \
        --heldout-persons 30 --heldout-seed S --set held-out --out out/pen_skill_bc_ias4f

The shipped policy's recipe (docs/results-learning.md): DAgger on the human skills and 400
synthetic ones,

    python train/pen_skill_bc.py --hand ias4f --n-demos 120 --dagger-iterations 5 \
        --episodes-per-iteration 60 --max-gradient-steps 36000 --synthetic-skills 400 \
        --randomise nominal,mass,internal_force_steps --loss huber --heldout-persons 30 \
        --heldout-seed S --set held-out --out out/ps_dagger

Learning across skills on persons drawn from the population. The training library is one
glove session per training skill of ``--train-persons`` persons of ``--train-seed``
(recorded into ``OUT/train_library.db``; unsuccessful sessions are no demonstrations and
are left out, :func:`ias_gym.learning.skill_split.split_skills`), or ``--train-db``. On
``IAS-PenSkill-v0`` restricted to it, the expert (Theorem 1 following the transferred skill)
is recorded with noise injection (DART, :func:`ias_gym.learning.dart.record_noisy_expert`,
as ``train/bc.py``), cloned into an SB3 PPO model
(:func:`ias_gym.learning.cloning.behaviour_clone`) and fine-tuned briefly by PPO
(:func:`ias_gym.learning.finetune.fine_tune`, the best policy on validation seeds of the
training skills kept). With ``--synthetic-skills N`` the library also holds N random
motions inside the hand's workspace (:mod:`ias_gym.skills.synthetic`); with
``--dagger-iterations K`` the learner is trained by DAgger
(:func:`ias_gym.learning.dagger.dagger`: the expert's episodes first, then K - 1
iterations with the learner in the loop) instead of cloned, and saved as ``bc.zip`` all
the same. Expert, learned, fine-tuned and random policies are then run once
per skill and ``--eval-seeds`` seed on four groups: training skills of training persons
(new seeds), held-out skills of training persons, and training and held-out skills of
``--heldout-persons`` persons of ``--heldout-seed`` (their glove sessions recorded after
training into ``OUT/heldout_persons.db``, unless ``--heldout-db`` gives them). Success per
group with its 95 % Wilson interval; ``--set`` states whether the held-out persons are
development or held-out data.

Writes into ``--out``: ``demos.db``, ``bc.zip``, ``bc_ppo.zip`` (SB3 zips that load
without unpickling: ``ias-gym evaluate --env IAS-PenSkill-v0 --policy OUT/bc.zip``),
``results.json`` and ``results.md``. Refuses to replace them without ``--overwrite``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Sequence
from functools import partial
from pathlib import Path
from typing import Any

from ias_gym.sim.hands import hand_names

ENV_ID = "IAS-PenSkill-v0"
OUTPUTS = ("demos.db", "bc.zip", "bc_ppo.zip", "results.json", "results.md")
#: Population seed of the training persons (development data by definition).
TRAIN_SEED = 5150
#: Held out of training: a faster variant of a trained motion (extrapolation in speed) and
#: a motion of its own (the pen put down, not held).
HELDOUT_SKILLS = "seesaw_fast,lift_place"
POLICIES = ("expert", "bc", "bc_ppo", "random")
#: DAgger's options and their defaults; they act only with --dagger-iterations > 1.
DAGGER = {
    "episodes_per_iteration": 60,
    "takeover": 0.02,
    "max_gradient_steps": 12000,
    "ensemble": 1,
}


def build_parser() -> argparse.ArgumentParser:
    """Command-line options."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--hand", default="ias4f", choices=hand_names(), help="robot hand")
    parser.add_argument("--n-demos", type=int, default=40, help="DART expert episodes")
    parser.add_argument("--out", required=True, metavar="DIR", help="output directory")
    parser.add_argument("--overwrite", action="store_true", help="replace existing outputs")
    parser.add_argument(
        "--train-persons", type=int, default=20, help="training persons of the population"
    )
    parser.add_argument(
        "--train-seed", type=int, default=TRAIN_SEED, help="population seed of the training persons"
    )
    parser.add_argument(
        "--train-db",
        default=None,
        help="train on this library instead of glove sessions of the training persons",
    )
    parser.add_argument(
        "--heldout-persons", type=int, default=30, help="held-out persons of the population"
    )
    parser.add_argument(
        "--heldout-seed",
        type=int,
        required=True,
        help="population seed of the held-out persons (one the training never saw)",
    )
    parser.add_argument(
        "--set",
        choices=("development", "held-out"),
        required=True,
        help="whether the held-out persons are development or held-out data",
    )
    parser.add_argument(
        "--heldout-db",
        default=None,
        help="glove sessions of the held-out persons (default: recorded into "
        "OUT/heldout_persons.db, reused if there)",
    )
    parser.add_argument("--heldout-skills", default=HELDOUT_SKILLS, help="comma-separated")
    parser.add_argument(
        "--skills",
        default="",
        metavar="SKILL,...",
        help="the glove skills recorded and evaluated (empty: all of them); a development "
        "split can leave the held-out skills of the final run out of sight",
    )
    parser.add_argument(
        "--synthetic-skills",
        type=int,
        default=0,
        help="random motions inside the hand's workspace added to the training library "
        "(ias_gym.skills.synthetic); the expert is then recorded as under --randomise",
    )
    parser.add_argument(
        "--noise", type=float, default=0.001, help="DART noise std [normalised torque]"
    )
    parser.add_argument(
        "--randomise",
        default="",
        metavar="FAMILY,...",
        help="record the expert under dynamics drawn per episode from these families of "
        "ias_gym.learning.randomised_dynamics (e.g. nominal,friction,mass,push,action_noise,"
        "internal_force_steps); empty: nominal dynamics",
    )
    parser.add_argument("--record-seed", type=int, default=0, help="seed of the first demo")
    parser.add_argument(
        "--dagger-iterations",
        type=int,
        default=1,
        help="1: clone the expert's --n-demos episodes (BC); K > 1: K - 1 DAgger iterations "
        "after them (ias_gym.learning.dagger, the learner in the loop, gated by --takeover), "
        "each of --episodes-per-iteration episodes; the learned policy is bc.zip either way",
    )
    # DAgger's own options: absent unless given (a BC run refuses them), defaults in DAGGER
    parser.add_argument(
        "--episodes-per-iteration",
        type=int,
        default=argparse.SUPPRESS,
        help=f"DAgger: episodes an iteration (default: {DAGGER['episodes_per_iteration']})",
    )
    parser.add_argument(
        "--takeover",
        type=float,
        default=argparse.SUPPRESS,
        help="DAgger: the expert acts where the learner's action is this far from its label "
        f"[normalised torque] (default: {DAGGER['takeover']})",
    )
    parser.add_argument(
        "--max-gradient-steps",
        type=int,
        default=argparse.SUPPRESS,
        help="DAgger: Adam steps of a cloning at most (fewer epochs on a large dataset) "
        f"(default: {DAGGER['max_gradient_steps']})",
    )
    parser.add_argument(
        "--ensemble",
        type=int,
        default=argparse.SUPPRESS,
        help=f"DAgger: clones per iteration, acting as their mean (default: {DAGGER['ensemble']})",
    )
    parser.add_argument("--epochs", type=int, default=100, help="cloning: passes over the data")
    parser.add_argument("--net-arch", default="256,256", help="hidden layers of actor, critic")
    parser.add_argument(
        "--loss",
        choices=("mse", "huber"),
        default="mse",
        help="cloning loss: the squared error or Huber's (a few of the expert's near-saturated "
        "labels, e.g. under --randomise, cannot dominate the fit)",
    )
    parser.add_argument(
        "--ppo-steps", type=int, default=8192, help="PPO fine-tuning environment steps"
    )
    parser.add_argument(
        "--critic-warmup", type=int, default=4096, help="first PPO steps, actor frozen"
    )
    parser.add_argument("--n-envs", type=int, default=2, help="PPO envs (sequential)")
    parser.add_argument("--val-episodes", type=int, default=4, help="validation episodes")
    parser.add_argument("--val-seed", type=int, default=2000, help="first validation seed")
    parser.add_argument("--eval-seeds", type=int, default=1, help="evaluation seeds per skill")
    parser.add_argument("--eval-seed", type=int, default=1000, help="first evaluation seed")
    parser.add_argument(
        "--max-eval-skills", type=int, default=0, help="per group at most N skills (0: all)"
    )
    parser.add_argument(
        "--robustness-episodes",
        type=int,
        default=0,
        help="episodes per disturbance class of the robustness suite, expert and BC on the "
        "held-out persons' training skills (0: none)",
    )
    parser.add_argument(
        "--robustness-seed", type=int, default=30000, help="first seed of the robustness suite"
    )
    parser.add_argument("--seed", type=int, default=0, help="training seed")
    parser.add_argument("--threads", type=int, default=1, help="torch threads")
    return parser


def _names(text: str) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


def record_sessions(db: Path, persons: Sequence[str], skills: Sequence[str]) -> None:
    """Record one glove session per person and skill into ``db`` (those missing there)."""
    from tqdm import tqdm

    from ias_gym.skills.db import SkillDB
    from ias_gym.skills.record import record_skills_spec

    have: set[tuple[str | None, str]] = set()
    if db.is_file():
        with SkillDB(db, readonly=True) as store:
            have = {(s.person_id, s.name) for s in store.list_skills()}
    todo = [(p, s) for p in persons for s in skills if (p, s) not in have]
    for person, skill in tqdm(todo, desc="glove sessions", unit="session"):
        record_skills_spec(
            "IAS-GloveGrasp-v0", "teleop", 1, db, progress=False, person_id=person, skill=skill
        )


def first_per_person_and_skill(summaries: Sequence[Any]) -> list[Any]:
    """The first session of each (person, skill) pair (a library may hold repeats)."""
    seen: set[tuple[str, str]] = set()
    out = []
    for s in sorted(summaries, key=lambda s: s.id):
        if (s.person_id, s.name) not in seen:
            seen.add((s.person_id, s.name))
            out.append(s)
    return out


def evaluate_group(
    policy_spec: str,
    db: str | None,
    ids: Sequence[int],
    hand: str,
    seeds: Sequence[int],
    label: str,
    visited: list[tuple[Any, Any]] | None = None,
) -> dict[str, Any]:
    """Run ``policy_spec`` once per skill of ``ids`` and seed; success and tracking errors.

    ``visited`` collects each step's (observation, action) when given.
    """
    from tqdm import tqdm

    from ias_gym.baselines.policies import load_policy
    from ias_gym.evaluation import make_env
    from ias_gym.rollout import rollout

    env = make_env(ENV_ID, hand=hand, skill_db=db, skill_ids=list(ids))
    policy = load_policy(policy_spec, env, seed=seeds[0])
    rows: list[dict[str, Any]] = []
    runs = [(i, s) for i in range(len(ids)) for s in seeds]
    try:
        for index, seed in tqdm(runs, desc=label, unit="episode", leave=False):
            trajectory = rollout(
                env,
                policy,
                seed,
                reset_options={"skill": index},
                keep_observations=visited is not None,
                keep_infos=False,
            )
            if visited is not None:
                assert trajectory.observations is not None
                visited.extend(zip(trajectory.observations[:-1], trajectory.actions, strict=True))
            info, length = trajectory.final_info, trajectory.length
            held = not trajectory.terminated and not info.get("sim_unstable", False)  # not dropped
            rows.append(
                {
                    "skill_id": int(ids[index]),
                    "success": bool(info["is_success"]),
                    "held": bool(held),
                    "length_s": length * env.unwrapped.config.control_dt,  # type: ignore[attr-defined]
                    "rms_position_error_mm": 1e3 * float(info["rms_position_error"]),
                    "rms_rotation_error_deg": math.degrees(float(info["rms_rotation_error"])),
                    "margin_error": float(info["margin_error"]),
                }
            )
    finally:
        env.close()
    return summarise(rows)


def open_loop_diagnosis(
    visited: Sequence[tuple[Any, Any]],
    train_observations: Any,
    models: dict[str, str],
    env_kwargs: dict[str, Any],
) -> dict[str, Any]:
    """Why a cloned policy fails where it does, measured on the expert's own states.

    Two numbers per group: how far the expert's observations lie outside the training
    data, in the policy's normalisation (largest ``|obs - mean| / std`` and its feature
    index), and each model's open-loop action error there (RMS over steps and
    components of model action minus expert action [normalised torque]; the expert itself
    drops the pen under action noise of about 0.002, ias_gym/learning/dart.py).
    """
    import numpy as np

    from ias_gym.baselines.policies import load_policy
    from ias_gym.evaluation import make_env
    from ias_gym.learning.normalisation import OBS_STD_FLOOR, observation_statistics

    obs = np.array([o for o, _ in visited], dtype=np.float32)
    expert = np.array([a for _, a in visited], dtype=np.float32)
    mean, std = observation_statistics(train_observations, OBS_STD_FLOOR)
    z = np.abs((obs - mean) / std).max(axis=0)
    out: dict[str, Any] = {
        "steps": len(obs),
        "max_abs_z": float(z.max()),
        "feature_of_max_z": int(z.argmax()),
    }
    env = make_env(ENV_ID, **env_kwargs)
    try:
        for name, path in models.items():
            policy = load_policy(path, env)
            actions = np.array([policy.predict(o, deterministic=True)[0] for o in obs])
            out[f"{name}_action_rms_error"] = float(np.sqrt(np.mean((actions - expert) ** 2)))
    finally:
        env.close()
    return out


def summarise(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Success rate (with its 95 % Wilson interval), held rate, and the tracking errors'
    means over the held episodes."""
    import numpy as np

    from ias_gym.rates import rate_json

    held = [r for r in rows if r["held"]]

    def mean(key: str) -> float | None:
        values = [r[key] for r in held if math.isfinite(r[key])]
        return float(np.mean(values)) if values else None

    return {
        "episodes": len(rows),
        "success_rate": float(np.mean([r["success"] for r in rows])) if rows else 0.0,
        "success": rate_json([r["success"] for r in rows]),
        "held_rate": len(held) / len(rows) if rows else 0.0,
        "mean_length_s": float(np.mean([r["length_s"] for r in rows])) if rows else 0.0,
        "rms_position_error_mean_mm": mean("rms_position_error_mm"),
        "rms_rotation_error_mean_deg": mean("rms_rotation_error_deg"),
        "margin_error_mean": mean("margin_error"),
        "episodes_detail": list(rows),
    }


def percent_interval(rate: dict[str, Any] | None) -> str:
    """A rate of the JSON (:meth:`ias_gym.rates.Rate.to_dict`) as :class:`~ias_gym.rates.Rate`
    prints it; ``"-"`` for none."""
    from ias_gym.rates import Rate

    return "-" if rate is None else str(Rate(rate["successes"], rate["trials"]))


def markdown(results: dict[str, Any]) -> str:
    """The results as a markdown table (one row per group and policy)."""

    def fmt(value: float | None, digits: int) -> str:
        return "-" if value is None else f"{value:.{digits}f}"

    n_persons, seed = results["heldout_population"]
    synthetic = results.get("synthetic_skills") or 0
    lines = [
        f"hand {results['hand']}; training: {len(results['train_persons'])} persons x "
        f"{results['train_skills']}{f' + {synthetic} synthetic' if synthetic else ''}; "
        f"method {results.get('method', 'bc')}; held-out skills {results['heldout_skills']}; "
        f"held-out persons: {n_persons} of population seed {seed} ({results['set']})",
        "",
        "| group | policy | episodes | success | held | mean length [s] | RMS pos. err. [mm] | "
        "RMS axis err. [deg] | margin err. [-] |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for group, per_policy in results["groups"].items():
        for name, s in per_policy.items():
            lines.append(
                f"| {group} | {name} | {s['episodes']} | {percent_interval(s['success'])} | "
                f"{s['held_rate']:.0%} | {s['mean_length_s']:.2f} | "
                f"{fmt(s['rms_position_error_mean_mm'], 2)} | "
                f"{fmt(s['rms_rotation_error_mean_deg'], 2)} | "
                f"{fmt(s['margin_error_mean'], 2)} |"
            )
    lines.append("")
    lines.append(
        "Errors are means over the episodes in which the pen was held to the end (`held`)."
    )
    lines += [
        "",
        "On the expert's states of each group: the largest |z| of an observation feature "
        "in the policy's normalisation, and the open-loop action error [normalised torque]:",
        "",
        "| group | steps | max abs z (feature) | BC action RMS error | BC+PPO action RMS error |",
        "|---|---|---|---|---|",
    ]
    for group, d in results.get("open_loop", {}).items():
        lines.append(
            f"| {group} | {d['steps']} | {d['max_abs_z']:.0f} (#{d['feature_of_max_z']}) | "
            f"{d['bc_action_rms_error']:.4f} | {d['bc_ppo_action_rms_error']:.4f} |"
        )
    robustness = results.get("robustness") or {}
    if robustness:
        names = list(robustness)
        lines += [
            "",
            "The robustness suite on the held-out persons' training skills (success per class):",
            "",
            "| class | " + " | ".join(names) + " |",
            "|---|" + "---|" * len(names),
        ]
        for k, row in enumerate(robustness[names[0]]):
            cells = [percent_interval(robustness[n][k]) for n in names]
            lines.append(f"| {row['disturbance']} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    """Split, record, clone, fine-tune, evaluate, write the table."""
    args = build_parser().parse_args(argv)
    from ias_gym.errors import IasGymError, InputError
    from ias_gym.glove.population import check_population, population_ids
    from ias_gym.glove.skills import SKILLS
    from ias_gym.outputs import atomic_output, prepare_output_dir

    try:  # before the heavy imports and any work
        given = [name for name in DAGGER if hasattr(args, name)]
        if given and args.dagger_iterations <= 1:
            flags = ", ".join("--" + name.replace("_", "-") for name in given)
            raise InputError(
                f"{flags} act only in DAgger; add --dagger-iterations K (K > 1) or drop them"
            )
        for name, default in DAGGER.items():
            setattr(args, name, getattr(args, name, default))
        if args.n_demos < 1:
            raise InputError(f"--n-demos must be >= 1, got {args.n_demos}")
        if args.dagger_iterations < 1 or args.episodes_per_iteration < 1 or args.ensemble < 1:
            raise InputError(
                "--dagger-iterations, --episodes-per-iteration and --ensemble must be >= 1"
            )
        if args.synthetic_skills < 0:
            raise InputError(f"--synthetic-skills must be >= 0, got {args.synthetic_skills}")
        skills = _names(args.skills) or list(SKILLS)
        unknown = sorted(set(skills + _names(args.heldout_skills)) - set(SKILLS))
        if unknown:
            raise InputError(f"--skills: unknown skills {unknown}; known: {', '.join(SKILLS)}")
        outside = sorted(set(_names(args.heldout_skills)) - set(skills))
        if outside:
            raise InputError(f"--heldout-skills {outside} are not among --skills; add them there")
        if not (math.isfinite(args.takeover) and args.takeover > 0) or args.max_gradient_steps < 1:
            raise InputError("--takeover must be finite and > 0, --max-gradient-steps >= 1")
        randomisation = None
        if args.randomise:  # the families named, checked before any work
            from ias_gym.learning.randomised_dynamics import Randomisation

            randomisation = Randomisation(families=tuple(_names(args.randomise)))
        check_population(args.train_persons, args.train_seed)
        check_population(args.heldout_persons, args.heldout_seed)
        if args.heldout_seed == args.train_seed:
            raise InputError(
                f"--heldout-seed {args.heldout_seed} is the training persons' seed; draw "
                "the held-out persons with another"
            )
        if args.train_db:  # a database that opens, before any work
            from ias_gym.errors import MissingFileError
            from ias_gym.skills.db import SkillDB

            if not Path(args.train_db).is_file():
                raise MissingFileError(f"--train-db: no skill database at {args.train_db}")
            with SkillDB(args.train_db, readonly=True) as db:
                db.list_skills()
        out = prepare_output_dir(args.out, OUTPUTS, overwrite=args.overwrite)
    except IasGymError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    import torch

    from ias_gym.learning.cloning import behaviour_clone
    from ias_gym.learning.dart import record_noisy_expert
    from ias_gym.learning.demonstrations import load_demonstrations
    from ias_gym.learning.finetune import KeepBestPolicy, fine_tune, make_vec_env
    from ias_gym.learning.skill_split import split_skills
    from ias_gym.skills.db import SkillDB

    torch.set_num_threads(args.threads)

    heldout_skills = _names(args.heldout_skills)
    heldout_persons = population_ids(args.heldout_persons, args.heldout_seed)
    if args.train_db:
        train_db = Path(args.train_db)
    else:
        train_db = out / "train_library.db"
        persons = population_ids(args.train_persons, args.train_seed)
        record_sessions(train_db, persons, [s for s in skills if s not in heldout_skills])
    with SkillDB(train_db, readonly=True) as db:
        summaries = db.list_skills()
    split = split_skills(summaries, heldout_skills, heldout_persons)
    if not split.train:
        print(f"error: no training skills left in {train_db}", file=sys.stderr)
        return 2
    by_id = {s.id: s for s in summaries}
    train_persons = sorted({by_id[i].person_id or "" for i in split.train})
    train_skills = sorted({by_id[i].name for i in split.train})
    print(f"training on {len(split.train)} skills: {train_persons} x {train_skills}")

    heldout_db = Path(args.heldout_db) if args.heldout_db else out / "heldout_persons.db"
    leaked = sorted(set(heldout_persons) & set(train_persons))
    if leaked:  # split_skills excludes them; a second check costs nothing
        raise AssertionError(f"held-out persons {leaked} in the training data")

    library = str(train_db)
    env_kwargs: dict[str, Any] = {
        "hand": args.hand,
        "skill_db": library,
        "skill_ids": list(split.train),
    }
    record_kwargs = env_kwargs
    if args.synthetic_skills > 0:
        from ias_gym.envs.pen_skill_env import PenSkillConfig
        from ias_gym.skills.synthetic import synthetic_references
        from ias_gym.skills.transfer import load_references

        cfg = PenSkillConfig(hand=args.hand)
        human = load_references(library, split.train, args.hand, cfg.control_dt, cfg.duration)
        synthetic = synthetic_references(
            args.synthetic_skills,
            [r.margin for r in human],
            args.hand,
            cfg.control_dt,
            cfg.duration,
            seed=args.seed,
        )
        record_kwargs = {"hand": args.hand, "references": (*human, *synthetic)}
    if randomisation is None and (args.synthetic_skills > 0 or args.dagger_iterations > 1):
        # recorded through the labelling of DAgger (references in memory, not a demo database)
        from ias_gym.learning.randomised_dynamics import NOMINAL

        randomisation = NOMINAL
    net_arch = [int(n) for n in args.net_arch.split(",")]
    start = time.perf_counter()
    observations: Any
    actions: Any
    returns: Any
    dagger_history: list[dict[str, Any]] = []
    learned = None
    if args.dagger_iterations > 1:
        from ias_gym.learning.dagger import dagger

        assert randomisation is not None
        run = dagger(
            ENV_ID,
            args.dagger_iterations,
            args.episodes_per_iteration,
            args.record_seed,
            initial_episodes=args.n_demos,
            expert_noise=args.noise,
            takeover=args.takeover,
            randomisation=randomisation,
            env_kwargs=record_kwargs,
            epochs=args.epochs,
            max_gradient_steps=args.max_gradient_steps,
            net_arch=net_arch,
            robust=args.loss == "huber",
            ensemble=args.ensemble,
        )
        learned, dagger_history = run.model, [r.as_json() for r in run.history]
        observations, actions, returns = run.dataset.observations, run.dataset.actions, None
    elif randomisation is not None:
        # Expert episodes under dynamics drawn per episode from the robustness suite's
        # families (ias_gym.learning.randomised_dynamics), every visited state labelled.
        import gymnasium as gym

        from ias_gym.learning.expert_labelling import expert_dataset

        steps = gym.spec(ENV_ID).max_episode_steps or 1  # labels per demonstration
        dataset, _ = expert_dataset(
            ENV_ID,
            args.n_demos * steps,
            seed=args.record_seed,
            randomisation=randomisation,
            env_kwargs=record_kwargs,
            expert_noise=args.noise,
        )
        observations, actions, returns = dataset.observations, dataset.actions, None
    else:
        demos_db = out / "demos.db"
        if demos_db.exists():  # --overwrite: a fresh recording, not appended to the old one
            for suffix in ("", "-wal", "-shm"):
                Path(f"{demos_db}{suffix}").unlink(missing_ok=True)
        record_noisy_expert(
            ENV_ID, args.n_demos, demos_db, args.noise, seed=args.record_seed, env_kwargs=env_kwargs
        )
        demos = load_demonstrations(demos_db, ENV_ID, source="expert")
        observations, actions, returns = demos.observations, demos.actions, demos.returns
    what = f"{args.dagger_iterations} DAgger iterations" if learned is not None else "recorded"
    print(
        f"{what}: {args.n_demos} expert demonstrations first, {len(actions)} labelled steps "
        f"in all, {time.perf_counter() - start:.0f} s"
    )

    # the DAgger learner was built on one env: it is fine-tuned on one
    n_envs = 1 if learned is not None else args.n_envs
    env = make_vec_env(ENV_ID, n_envs, seed=args.seed, env_kwargs=env_kwargs)
    start = time.perf_counter()
    if learned is not None:
        model = learned
        model.set_env(env)
    else:
        model = behaviour_clone(
            env,
            observations,
            actions,
            returns,
            epochs=args.epochs,
            net_arch=net_arch,
            seed=args.seed,
            robust=args.loss == "huber",
        )
    with atomic_output(out / "bc.zip", overwrite=True) as tmp:
        model.save(tmp)
    print(f"saved the cloned policy to {out / 'bc.zip'} ({time.perf_counter() - start:.0f} s)")

    start = time.perf_counter()
    keep_best = None
    if args.val_episodes > 0:
        seeds = range(args.val_seed, args.val_seed + args.val_episodes)
        keep_best = KeepBestPolicy(ENV_ID, seeds, args.ppo_steps // 2, env_kwargs=env_kwargs)
    fine_tune(model, args.ppo_steps, critic_warmup=args.critic_warmup, keep_best=keep_best)
    with atomic_output(out / "bc_ppo.zip", overwrite=True) as tmp:
        model.save(tmp)
    history = [] if keep_best is None else keep_best.history
    print(
        f"saved the fine-tuned policy to {out / 'bc_ppo.zip'} ({model.num_timesteps} steps, "
        f"{time.perf_counter() - start:.0f} s; validation {history})"
    )
    env.close()

    # Recorded after training (missing sessions only): nothing of them can reach training.
    # The training persons' held-out skills go there too (the held-out-skill group).
    record_sessions(heldout_db, heldout_persons, skills)
    record_sessions(heldout_db, train_persons, heldout_skills)
    with SkillDB(heldout_db, readonly=True) as db:
        heldout_split = split_skills(
            first_per_person_and_skill(db.list_skills()), heldout_skills, heldout_persons
        )
    eval_seeds = list(range(args.eval_seed, args.eval_seed + args.eval_seeds))
    specs = {
        "expert": "expert",
        "bc": str(out / "bc.zip"),
        "bc_ppo": str(out / "bc_ppo.zip"),
        "random": "random",
    }
    libraries = {
        "train": (library, split.train),
        "heldout_skill": (str(heldout_db), heldout_split.heldout_skill),
        "heldout_person": (str(heldout_db), heldout_split.heldout_person),
        "heldout_both": (str(heldout_db), heldout_split.heldout_both),
    }
    groups: dict[str, dict[str, Any]] = {}
    diagnosis: dict[str, dict[str, Any]] = {}
    for group, (db_path, ids) in libraries.items():
        if args.max_eval_skills > 0:
            ids = ids[: args.max_eval_skills]
        if not ids:
            continue
        visited: list[tuple[Any, Any]] = []
        groups[group] = {
            name: evaluate_group(
                spec,
                db_path,
                ids,
                args.hand,
                eval_seeds,
                f"{group} / {name}",
                visited if name == "expert" else None,
            )
            for name, spec in specs.items()
        }
        diagnosis[group] = open_loop_diagnosis(
            visited, observations, {n: specs[n] for n in ("bc", "bc_ppo")}, env_kwargs
        )
        print(
            group,
            {n: f"{s['success_rate']:.0%}" for n, s in groups[group].items()},
            flush=True,
        )
    robustness: dict[str, list[dict[str, Any]]] = {}
    if args.robustness_episodes > 0 and heldout_split.heldout_person:
        from ias_gym.baselines.policies import load_policy
        from ias_gym.robustness import run_robustness

        suite_env = {
            "hand": args.hand,
            "skill_db": str(heldout_db),
            "skill_ids": list(heldout_split.heldout_person),
        }
        for name in ("expert", "bc"):
            rows = run_robustness(
                ENV_ID,
                partial(load_policy, specs[name]),
                args.robustness_episodes,
                args.robustness_seed,
                env_kwargs=suite_env,
                progress=True,
                name=name,
            )
            robustness[name] = [row.as_json() for row in rows]
    results = {
        "env": ENV_ID,
        "set": args.set,
        "hand": args.hand,
        "train_population": None if args.train_db else [args.train_persons, args.train_seed],
        "heldout_population": [args.heldout_persons, args.heldout_seed],
        "train_db": str(train_db),
        "heldout_db": str(heldout_db),
        "train_persons": train_persons,
        "train_skills": train_skills,
        "heldout_skills": heldout_skills,
        "skills": skills,
        "synthetic_skills": args.synthetic_skills,
        "heldout_persons": heldout_persons,
        "n_demos": args.n_demos,
        "method": "dagger" if args.dagger_iterations > 1 else "bc",
        "dagger": {
            "iterations": args.dagger_iterations,
            "episodes_per_iteration": args.episodes_per_iteration,
            "takeover": args.takeover,
            "max_gradient_steps": args.max_gradient_steps,
            "ensemble": args.ensemble,
            "history": dagger_history,
        }
        if args.dagger_iterations > 1
        else None,
        "demo_steps": len(actions),
        "randomise": _names(args.randomise),
        "noise": args.noise,
        "epochs": args.epochs,
        "loss": args.loss,
        "ppo_steps": int(model.num_timesteps),
        "validation": [list(h) for h in history],
        "eval_seeds": eval_seeds,
        "groups": groups,
        "open_loop": diagnosis,
        "robustness": robustness,
    }
    with atomic_output(out / "results.json", overwrite=True) as tmp:
        tmp.write_text(json.dumps(results, indent=1) + "\n")
    table = markdown(results)
    with atomic_output(out / "results.md", overwrite=True) as tmp:
        tmp.write_text(table)
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""DAgger with the analytic expert as teacher under randomised dynamics, beside behaviour
cloning from as many expert labels; both evaluated on the robustness suite, held-out seeds.

    python train/dagger.py --env IAS-PenSlide-v0 --iterations 6 --initial-episodes 30 \\
        --episodes-per-iteration 15 --max-gradient-steps 12000 --ensemble 3 \\
        --curve-episodes 20 --seed 7 --out out/dagger_slide.zip

The results of the runs in docs/dagger_results.json, with the commands that reproduce them
and their held-out seeds, are on docs/results-learning.md.

What it does (:mod:`ias_gym.learning.dagger`, :mod:`ias_gym.learning.expert_labelling` and
:mod:`ias_gym.learning.randomised_dynamics` have the details):

- **DAgger** (Ross, Gordon & Bagnell 2011): iteration 0 clones expert rollouts; iteration
  ``i`` rolls out the mixture (expert with probability ``beta_decay ** i`` per step, else
  the learner), the expert, run in the shadow of every step (it is privileged and
  stateful: it reads the simulator and keeps a memory along the episode), labels every
  visited state, the labels are aggregated and a new learner is cloned on all of them.
- **Randomised dynamics**: every training episode draws one family of the robustness suite
  (nominal, friction, mass, push, observation noise, action delay, action noise,
  internal-force steps) and its parameters from ranges that contain the suite's fixed
  classes with a margin (friction and mass x0.6-1.4, push 0.1-0.4 N for 30-70 ms,
  observation noise x0-1.5 of the class's, delay 0-2 steps, action noise 0-0.003,
  internal-force steps 0-0.15 N); ``--families`` chooses the families (a name repeated
  weights it; ``combined`` draws every disturbance at once).
- **Baseline**: behaviour cloning on expert rollouts under the same training dynamics,
  cut at exactly as many labels as DAgger gathered, cloned with the same budget.
- **Evaluation**: every class of :data:`ias_gym.robustness.DISTURBANCES` on seeds from
  ``--eval-seed`` (default 100000; training reset seeds are all below it), success rate
  with its 95 % Wilson interval (:class:`ias_gym.rates.Rate`).

Writes ``--out`` (the DAgger policy) and ``--out`` with ``_bc`` before the suffix (the
baseline), SB3 zips that load without unpickling (``ias-gym evaluate --env ID --policy
FILE.zip``, ``ias-gym robustness --policy FILE.zip``), and ``--results`` (JSON, units in
the keys). ``--curve-episodes N`` also evaluates every iteration's learner on ``N``
development episodes of the training distribution (seeds and draws never used for
training), the learning curve.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any


def build_parser() -> argparse.ArgumentParser:
    """Command-line options."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--env", default="IAS-PenSlide-v0", help="a pen task")
    parser.add_argument("--iterations", type=int, default=6, help="DAgger iterations (>= 1)")
    parser.add_argument(
        "--episodes-per-iteration", type=int, default=15, help="episodes collected per iteration"
    )
    parser.add_argument("--seed", type=int, default=0, help="training seed")
    parser.add_argument("--out", required=True, metavar="PATH.zip", help="DAgger policy to write")
    parser.add_argument(
        "--results", default=None, metavar="PATH.json", help="results JSON (default: beside --out)"
    )
    parser.add_argument("--beta-decay", type=float, default=0.5, help="beta_i = decay ** i")
    parser.add_argument(
        "--initial-episodes",
        type=int,
        default=None,
        help="expert episodes of iteration 0 (default: --episodes-per-iteration)",
    )
    parser.add_argument(
        "--expert-noise",
        type=float,
        default=0.001,
        help="noise on the expert's executed actions, labels clean (DART) [normalised torque]",
    )
    parser.add_argument(
        "--takeover",
        type=float,
        default=None,
        help="the expert acts where the learner's action is further than this from its label "
        "in any joint (HG-DAgger's gate) [normalised torque] (default: no gate)",
    )
    parser.add_argument("--epochs", type=int, default=100, help="cloning epochs per iteration")
    parser.add_argument(
        "--max-gradient-steps",
        type=int,
        default=6000,
        help="cap on the cloning's Adam steps per iteration (0: none)",
    )
    parser.add_argument(
        "--warm-start",
        action="store_true",
        help="train one learner on over the iterations (else a new one each iteration); "
        "the BC baseline then gets DAgger's total number of Adam steps",
    )
    parser.add_argument(
        "--loss",
        choices=("huber", "mse"),
        default="huber",
        help="cloning loss of DAgger and of the BC baseline: Huber's (a few of the expert's "
        "near-saturated labels cannot dominate the fit) or the squared error",
    )
    parser.add_argument(
        "--obs-clip",
        type=float,
        default=10.0,
        help="normalised observations are clipped to +- this in DAgger's and the BC "
        "baseline's policies [observation standard deviations]",
    )
    parser.add_argument(
        "--ensemble",
        type=int,
        default=1,
        help="clones per iteration (and for the BC baseline), acting as their mean, saved as "
        "one SB3 model (ias_gym.learning.ensemble)",
    )
    parser.add_argument("--no-randomisation", action="store_true", help="nominal dynamics only")
    parser.add_argument(
        "--families",
        default=None,
        help="comma-separated randomisation families to draw from, a name repeated to weight "
        "it; 'combined' draws every disturbance at once; None: one at a time, "
        "ias_gym.learning.randomised_dynamics.SINGLE_FAMILIES",
    )
    parser.add_argument("--no-baseline", action="store_true", help="skip the BC baseline")
    parser.add_argument(
        "--eval-episodes", type=int, default=50, help="held-out episodes per class (0: skip)"
    )
    parser.add_argument("--eval-seed", type=int, default=100_000, help="first held-out seed")
    parser.add_argument(
        "--curve-episodes",
        type=int,
        default=0,
        help="development episodes per iteration for the learning curve (0: none)",
    )
    parser.add_argument("--workers", type=int, default=1, help="evaluation worker processes")
    parser.add_argument("--threads", type=int, default=1, help="torch threads")
    parser.add_argument("--overwrite", action="store_true", help="replace existing outputs")
    return parser


def baseline_path(out: Path) -> Path:
    """The baseline's zip: ``--out`` with ``_bc`` before the suffix."""
    return out.with_name(f"{out.stem}_bc{out.suffix or '.zip'}")


def evaluate_rows(
    env_id: str, policy: Path, episodes: int, seed: int, workers: int
) -> dict[str, dict[str, Any]]:
    """Success per disturbance class with its Wilson interval, on seeds from ``seed``."""
    from ias_gym.rates import Rate
    from ias_gym.robustness import run_robustness_spec
    from ias_gym.runtime.jobs import Backend

    rows = run_robustness_spec(
        env_id,
        str(policy),
        episodes=episodes,
        seed=seed,
        progress=True,
        backend=Backend.from_options(workers),
    )
    return {
        r.disturbance: Rate(round(r.success_rate * r.episodes), r.episodes).to_dict() for r in rows
    }


def development_curve_point(
    env_id: str, model: Any, seed: int, episodes: int, randomisation: Any
) -> dict[str, Any]:
    """The learner alone on ``episodes`` development episodes of the training distribution.

    Run ``seed`` + :data:`DEVELOPMENT_RUN` draws the dynamics (never a training run's) and
    their reset seeds (all below the held-out seeds).
    """
    from ias_gym.learning.expert_labelling import collect_episode
    from ias_gym.learning.randomised_dynamics import episode_dynamics
    from ias_gym.rates import Rate

    outcomes = []
    for k in range(episodes):
        dynamics = episode_dynamics(DEVELOPMENT_RUN + seed, k, randomisation)
        episode = collect_episode(env_id, dynamics, model, 0.0)
        outcomes.append(episode.trajectory.is_success)
    return Rate.of(outcomes).to_dict()


#: Offset of the run seed that draws the development episodes of the learning curve.
DEVELOPMENT_RUN = 1_000_000


def main(argv: Sequence[str] | None = None) -> int:
    """Train DAgger and the BC baseline, save both, evaluate both, write the results."""
    args = build_parser().parse_args(argv)
    import gymnasium as gym
    import torch

    from ias_gym.errors import InputError
    from ias_gym.learning.dagger import cloning_epochs, dagger
    from ias_gym.learning.ensemble import clone_ensemble
    from ias_gym.learning.expert_labelling import check_pen_task, expert_dataset
    from ias_gym.learning.randomised_dynamics import (
        DEFAULT_RANDOMISATION,
        HELD_OUT_SEED_START,
        NOMINAL,
        Randomisation,
    )

    out = Path(args.out)
    results_path = Path(args.results) if args.results else out.with_suffix(".json")
    try:
        check_pen_task(args.env)
        if args.iterations < 1:
            raise InputError(f"--iterations must be >= 1, got {args.iterations}")
        if args.episodes_per_iteration < 1:
            raise InputError(
                f"--episodes-per-iteration must be >= 1, got {args.episodes_per_iteration}"
            )
        if args.eval_episodes and args.eval_seed < HELD_OUT_SEED_START:
            raise InputError(
                f"--eval-seed must be >= {HELD_OUT_SEED_START} (training seeds lie below it)"
            )
        if args.ensemble < 1:
            raise InputError(f"--ensemble must be >= 1, got {args.ensemble}")
        if args.ensemble > 1 and args.warm_start:
            raise InputError("--ensemble > 1 clones afresh each iteration; drop --warm-start")
        if args.takeover is not None and not (math.isfinite(args.takeover) and args.takeover > 0):
            raise InputError(f"--takeover must be a positive number, got {args.takeover}")
        if not (math.isfinite(args.obs_clip) and args.obs_clip > 0):
            raise InputError(f"--obs-clip must be a positive number, got {args.obs_clip}")
        if out.suffix != ".zip":
            raise InputError(f"--out must end in .zip, got {out}")
        outputs = [out, results_path] + ([] if args.no_baseline else [baseline_path(out)])
        existing = [str(p) for p in outputs if p.exists()]
        if existing and not args.overwrite:
            raise InputError(f"{', '.join(existing)} exist; pass --overwrite to replace them")
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2

    try:
        if args.no_randomisation:
            randomisation = NOMINAL
        elif args.families:
            randomisation = Randomisation(families=tuple(args.families.split(",")))
        else:
            randomisation = DEFAULT_RANDOMISATION
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    torch.set_num_threads(args.threads)
    max_steps = args.max_gradient_steps or None
    curve: list[dict[str, Any]] = []
    totals = {"env_steps": 0, "wall_time_s": 0.0}  # so far, for the curve (no evaluation time)

    def on_iteration(record: Any, model: Any) -> None:
        print(
            f"iteration {record.iteration}: beta {record.beta:.3g}, +{record.labels_added} "
            f"pairs ({record.dataset_size}), mixture success {record.rollout_success_rate:.2f}, "
            f"collect {record.collect_s:.0f} s, train {record.train_s:.0f} s",
            flush=True,
        )
        totals["env_steps"] += record.env_steps
        totals["wall_time_s"] += record.collect_s + record.train_s
        if args.curve_episodes:
            point = development_curve_point(
                args.env, model, args.seed, args.curve_episodes, randomisation
            )
            curve.append(
                {
                    "iteration": record.iteration,
                    "dataset_size": record.dataset_size,
                    **totals,
                    **point,
                }
            )
            print(f"  development success {point['success_rate']:.2f}", flush=True)

    start = time.perf_counter()
    result = dagger(
        args.env,
        args.iterations,
        args.episodes_per_iteration,
        args.seed,
        beta_decay=args.beta_decay,
        initial_episodes=args.initial_episodes,
        expert_noise=args.expert_noise,
        takeover=args.takeover,
        randomisation=randomisation,
        epochs=args.epochs,
        max_gradient_steps=max_steps,
        warm_start=args.warm_start,
        robust=args.loss == "huber",
        obs_clip=args.obs_clip,
        ensemble=args.ensemble,
        on_iteration=on_iteration,
    )
    dagger_s = time.perf_counter() - start
    out.parent.mkdir(parents=True, exist_ok=True)
    result.model.save(out)
    print(f"saved the DAgger policy to {out} ({dagger_s:.0f} s)", flush=True)

    labels = len(result.dataset)
    bc_s = None
    bc_point: dict[str, Any] | None = None
    baseline_epochs: int | None = None
    if not args.no_baseline:
        start = time.perf_counter()
        data, bc_episodes = expert_dataset(
            args.env,
            labels,
            args.seed,
            randomisation=randomisation,
            expert_noise=args.expert_noise,
        )
        if args.warm_start:  # as many Adam steps as DAgger made in all
            total = sum(r.gradient_steps for r in result.history)
            baseline_epochs = max(1, round(total / math.ceil(labels / 256)))
        else:  # as many as DAgger's last cloning
            baseline_epochs = cloning_epochs(labels, args.epochs, 256, max_steps)
        baseline = clone_ensemble(
            gym.make(args.env),
            data.observations,
            data.actions,
            args.ensemble,
            args.seed,
            epochs=baseline_epochs,
            progress=False,
            robust=args.loss == "huber",
            obs_clip=args.obs_clip,
        )
        baseline.save(baseline_path(out))
        bc_s = time.perf_counter() - start
        print(f"saved the BC baseline to {baseline_path(out)} ({bc_s:.0f} s)", flush=True)
        if args.curve_episodes:
            bc_point = {
                "dataset_size": labels,
                "env_steps": sum(e.trajectory.length for e in bc_episodes),
                "wall_time_s": bc_s,
                **development_curve_point(
                    args.env, baseline, args.seed, args.curve_episodes, randomisation
                ),
            }
            print(f"  development success of BC {bc_point['success_rate']:.2f}", flush=True)

    evaluation: dict[str, Any] = {}
    eval_s = None
    if args.eval_episodes:
        start = time.perf_counter()
        evaluation["dagger"] = evaluate_rows(
            args.env, out, args.eval_episodes, args.eval_seed, args.workers
        )
        if not args.no_baseline:
            evaluation["bc"] = evaluate_rows(
                args.env, baseline_path(out), args.eval_episodes, args.eval_seed, args.workers
            )
        eval_s = time.perf_counter() - start
        print_table(evaluation)

    report = {
        "env": args.env,
        "method": "DAgger (Ross et al. 2011), analytic expert as teacher, randomised dynamics",
        "train_seed": args.seed,
        "iterations": args.iterations,
        "episodes_per_iteration": args.episodes_per_iteration,
        "beta_decay": args.beta_decay,
        "initial_episodes": args.initial_episodes or args.episodes_per_iteration,
        "expert_noise": args.expert_noise,
        "takeover": args.takeover,
        "epochs": args.epochs,
        "max_gradient_steps": max_steps,
        "warm_start": args.warm_start,
        "loss": args.loss,
        "obs_clip": args.obs_clip,
        "ensemble": args.ensemble,
        "bc_epochs": baseline_epochs,
        "expert_labels": labels,
        "randomisation": dataclasses.asdict(randomisation),
        "history": [r.as_json() for r in result.history],
        "development_curve": curve,
        "bc_development_point": bc_point,
        "evaluation_set": "held-out",
        "evaluation_first_seed": args.eval_seed,
        "evaluation_episodes_per_class": args.eval_episodes,
        "evaluation": evaluation,
        "wall_time_s": {"dagger": dagger_s, "bc": bc_s, "evaluation": eval_s},
        "torch_threads": args.threads,
        "policies": {
            "dagger": str(out),
            "bc": None if args.no_baseline else str(baseline_path(out)),
        },
    }
    results_path.parent.mkdir(parents=True, exist_ok=True)
    results_path.write_text(json.dumps(report, indent=2) + "\n")
    print(f"wrote {results_path}")
    return 0


def print_table(evaluation: dict[str, dict[str, dict[str, Any]]]) -> None:
    """Success per class and method, with the 95 % intervals."""
    methods = list(evaluation)
    classes = list(next(iter(evaluation.values())))
    print(f"{'class':28s}" + "".join(f"{m:>24s}" for m in methods))
    for name in classes:
        cells = []
        for m in methods:
            r = evaluation[m][name]
            cells.append(
                f"{100 * r['success_rate']:5.0f} % [{100 * r['ci95_low']:3.0f}, "
                f"{100 * r['ci95_high']:3.0f}]"
            )
        print(f"{name:28s}" + "".join(f"{c:>24s}" for c in cells))


if __name__ == "__main__":
    sys.exit(main())

"""Train a residual assistant (PPO, SB3) on top of an assistant, operator in the loop.

    PYTHONPATH=$PWD python train/assist_residual.py --timesteps 20000 --out out/assist_residual.zip
    PYTHONPATH=$PWD python train/assist_residual.py --base observation --db out/library.db \
        --impairment none --impairment sampled --impairment stops --out out/obs_residual.zip

``--persons`` development persons drawn from the population with ``--population-seed``
(the table's persons are another draw), an impairment spec (``--impairment``, repeatable;
default: every family at its default and none) and a skill drawn at random per episode
(``ias_gym.learning.assist_residual``). ``--base analytic``: measure the result with
``train/assist_table.py --residual OUT``; ``--base observation``: with
``train/assist_population.py --residual OUT``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from tqdm import tqdm

from ias_gym.assist.skill_templates import load_templates
from ias_gym.errors import InputError
from ias_gym.glove.impairment_spec import Impairment
from ias_gym.glove.impairments import IMPAIRMENTS
from ias_gym.glove.operator import OPERATORS
from ias_gym.glove.population import population_ids
from ias_gym.learning.assist_residual import BASE_ATTRIBUTE, BASES, ResidualAssistEnv
from ias_gym.outputs import atomic_output, check_output_file


class Bar(BaseCallback):
    """A tqdm progress bar over the environment steps."""

    def __init__(self, total: int) -> None:
        super().__init__()
        self.bar = tqdm(total=total, desc="residual PPO steps")

    def _on_step(self) -> bool:
        self.bar.update(self.training_env.num_envs)
        return True

    def _on_training_end(self) -> None:
        self.bar.close()


def main(argv: list[str] | None = None) -> int:
    """Train and save (arguments: ``--help``)."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--timesteps", type=int, default=20_000, help="PPO env steps")
    parser.add_argument("--persons", type=int, default=8, help="development persons")
    parser.add_argument(
        "--population-seed", type=int, default=62, help="seed of the development persons' draw"
    )
    parser.add_argument("--seed", type=int, default=0, help="PPO's and the episodes' draw")
    parser.add_argument(
        "--db", default=None, help="skill library of the base assistant (None: the shipped one)"
    )
    parser.add_argument(
        "--base",
        choices=BASES,
        default="analytic",
        help="the assistant under the residual: the one on observations or the analytic one",
    )
    parser.add_argument(
        "--impairment",
        action="append",
        default=None,
        metavar="SPEC",
        help=f"an impairment spec drawn per episode, repeatable (None: {' '.join(IMPAIRMENTS)})",
    )
    parser.add_argument(
        "--learning-rate",
        type=float,
        default=1e-4,
        help="PPO's (3e-4 let the residual's mean drift: worse than the analytic assistant)",
    )
    parser.add_argument("--n-steps", type=int, default=400, help="PPO rollout length")
    parser.add_argument(
        "--operator",
        choices=OPERATORS,
        default="closed_loop",
        help="the simulated person: in the loop, or the open script",
    )
    parser.add_argument("--out", default="out/assist_residual.zip", help="the model (SB3 zip)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    args = parser.parse_args(argv)
    try:
        out = check_output_file(args.out, overwrite=args.overwrite, what="--out")
        persons = population_ids(args.persons, args.population_seed)
        specs = args.impairment or list(IMPAIRMENTS)
        for spec in specs:
            Impairment.make(spec)
        if args.db is not None and not Path(args.db).is_file():
            raise InputError(f"--db {args.db}: no such skill library (ias-gym assist library)")
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    templates = load_templates(args.db) if args.base == "analytic" else {}
    env = ResidualAssistEnv(
        templates, persons, specs, operator=args.operator, base=args.base, db=args.db
    )
    model = PPO(
        "MlpPolicy",
        env,
        n_steps=args.n_steps,
        batch_size=min(100, args.n_steps),
        n_epochs=5,
        learning_rate=args.learning_rate,
        # start near zero: the residual begins as the analytic assistant alone
        policy_kwargs={"log_std_init": -2.0},
        seed=args.seed,
        verbose=0,
    )
    setattr(model, BASE_ATTRIBUTE, args.base)  # saved in the model's JSON, checked on load
    model.learn(args.timesteps, callback=Bar(args.timesteps))
    with atomic_output(out, overwrite=args.overwrite) as tmp:
        model.save(tmp)
    env.close()
    print(f"saved {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

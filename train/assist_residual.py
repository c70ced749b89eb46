"""Train the residual assistant (PPO, SB3) on top of the analytic one, operator in the loop.

    PYTHONPATH=$PWD python train/assist_residual.py --timesteps 20000 --out out/assist_residual.zip

Persons p3-p6 (development persons; the table's held-out persons are others), every
impairment and skill drawn at random per episode (``ias_gym.learning.assist_residual``).
Measure the result with ``train/assist_table.py --residual OUT``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from tqdm import tqdm

from ias_gym.assist.skill_templates import load_templates
from ias_gym.glove.impairments import IMPAIRMENTS
from ias_gym.learning.assist_residual import ResidualAssistEnv


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
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--timesteps", type=int, default=20_000)
    parser.add_argument("--persons", default="p3,p4,p5,p6")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--db", default=None, help="skill library of the analytic assistant (default: shipped)"
    )
    parser.add_argument(
        "--learning-rate",
        type=float,
        default=1e-4,
        help="PPO's (3e-4 let the residual's mean drift: worse than the analytic assistant)",
    )
    parser.add_argument("--n-steps", type=int, default=400, help="PPO rollout length")
    parser.add_argument("--out", default="out/assist_residual.zip")
    parser.add_argument("--overwrite", action="store_true")
    args = parser.parse_args(argv)
    out = Path(args.out)
    if out.exists() and not args.overwrite:
        print(f"{out} exists (--overwrite)", file=sys.stderr)
        return 2
    out.parent.mkdir(parents=True, exist_ok=True)
    env = ResidualAssistEnv(load_templates(args.db), args.persons.split(","), list(IMPAIRMENTS))
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
    model.learn(args.timesteps, callback=Bar(args.timesteps))
    model.save(out)
    env.close()
    print(f"saved {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

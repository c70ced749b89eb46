"""The grip-transform controller's cost per control step, and expert vs random rollout rates.

Run: ``python bench/bench_controller.py [--steps N] [--json FILE]``. For each pen task: the
controller's compute per control step (median and p90 [us], and the fraction of the 10 ms
control period), then rollout rates in env steps per second, measured side by side in the
same run: the expert (env step + controller) against uniform random actions (env step only;
resets included).

Then the controller's time per env and step for 1 and 8 envs in this process: ``serial``
(one :class:`ExpertPolicy` per env, called in turn) against ``batched`` (one
:class:`BatchedExpert` computing every env's step at once), in alternating blocks.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np
from report import Report, Table

import ias_gym  # noqa: F401
from ias_gym.baselines.expert import BatchedExpert, ExpertPolicy

ENV_IDS = ("IAS-PenSlide-v0", "IAS-PenRotate-v0")


def controller_times(env_id: str, steps: int) -> np.ndarray:
    """Seconds per controller call along an expert episode (the env steps are not timed)."""
    env = gym.make(env_id)
    expert = ExpertPolicy(env)
    obs, _ = env.reset(seed=0)
    times = []
    for _ in range(steps):
        t0 = time.perf_counter()
        action, _ = expert.predict(obs)
        times.append(time.perf_counter() - t0)
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            obs, _ = env.reset()
            expert.reset()
    return np.array(times)


class Rollout:
    """An env stepped by the expert or by random actions, resumable block by block."""

    def __init__(self, env_id: str, policy: str) -> None:
        self.env = gym.make(env_id)
        self.env.action_space.seed(0)
        self.expert = ExpertPolicy(self.env) if policy == "expert" else None
        self.obs, _ = self.env.reset(seed=0)

    def rate(self, steps: int) -> float:
        """Run ``steps`` env steps (resets included); return steps per second."""
        t0 = time.perf_counter()
        for _ in range(steps):
            if self.expert is not None:
                action = self.expert.predict(self.obs)[0]
            else:
                action = self.env.action_space.sample()
            self.obs, _, terminated, truncated, _ = self.env.step(action)
            if terminated or truncated:
                self.obs, _ = self.env.reset()
                if self.expert is not None:
                    self.expert.reset()
        return steps / (time.perf_counter() - t0)


def rollout_rates(env_id: str, steps: int, blocks: int = 10) -> tuple[float, float]:
    """Median steps/s of the expert and of random actions, in alternating blocks.

    Alternating makes both see the same machine: this VM's speed drifts by tens of percent
    over seconds, which back-to-back runs would put into the ratio.
    """
    expert, random = Rollout(env_id, "expert"), Rollout(env_id, "random")
    expert_rates, random_rates = [], []
    for _ in range(blocks):
        expert_rates.append(expert.rate(steps // blocks))
        random_rates.append(random.rate(steps // blocks))
    return float(np.median(expert_rates)), float(np.median(random_rates))


class Fleet:
    """``n`` envs stepped by their experts, serially or batched; times the controller only."""

    def __init__(self, env_id: str, n: int, batched: bool) -> None:
        self.envs = [gym.make(env_id) for _ in range(n)]
        for i, env in enumerate(self.envs):
            env.reset(seed=i)
        self.batched = BatchedExpert(self.envs) if batched else None
        self.serial = [ExpertPolicy(env) for env in self.envs]
        shape = self.envs[0].observation_space.shape
        assert shape is not None
        self.obs_shape = shape
        self.times: list[float] = []

    def actions(self) -> list[np.ndarray]:
        if self.batched is not None:
            return list(self.batched.actions())
        obs = np.zeros(self.obs_shape)  # the expert reads the simulation, not obs
        return [expert.predict(obs)[0] for expert in self.serial]

    def block(self, steps: int) -> None:
        """``steps`` control steps of every env; appends seconds per env and step."""
        n = len(self.envs)
        for _ in range(steps):
            t0 = time.perf_counter()
            actions = self.actions()
            self.times.append((time.perf_counter() - t0) / n)
            for i, (env, action) in enumerate(zip(self.envs, actions, strict=True)):
                _, _, terminated, truncated, _ = env.step(action)
                if terminated or truncated:
                    env.reset()
                    if self.batched is not None:
                        self.batched.reset(i)
                    else:
                        self.serial[i].reset()


#: The goal for the batched controller at 8 envs [us per env and step].
GOAL_BATCHED_US = 300.0


def batch_rows(
    table: Table, env_id: str, steps: int, sizes: tuple[int, ...] = (1, 8), blocks: int = 10
) -> float:
    """Add per-env controller time, serial vs batched, for each number of envs to ``table``;
    returns the batched median at the largest size [us]."""
    for n in sizes:
        serial, batched = Fleet(env_id, n, False), Fleet(env_id, n, True)
        per_block = max(1, steps // (blocks * n))
        for _ in range(blocks):
            serial.block(per_block)
            batched.block(per_block)
        s, b = np.array(serial.times) * 1e6, np.array(batched.times) * 1e6
        table.row(
            env_id,
            str(n),
            f"{np.median(s):.0f}",
            f"{np.percentile(s, 90):.0f}",
            f"{np.median(b):.0f}",
            f"{np.percentile(b, 90):.0f}",
            f"{np.median(s) / np.median(b):.2f}",
        )
    return float(np.median(b))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000, help="control steps per measurement")
    report, args = Report.start(parser)
    table = report.table(
        f"The expert's controller per control step along its own episodes ({args.steps} "
        "steps, the env steps not timed), then rollouts in 10 alternating blocks of "
        f"{args.steps // 10} steps: the expert (env step + controller) against random actions, "
        "resets included",
        [
            "env",
            "controller median [us]",
            "controller p90 [us]",
            "of the control period",
            "expert [steps/s]",
            "random [steps/s]",
            "expert / random",
        ],
    )
    for env_id in ENV_IDS:
        t = controller_times(env_id, args.steps)
        period = gym.make(env_id).unwrapped.config.control_dt  # type: ignore[attr-defined]
        expert, random = rollout_rates(env_id, args.steps)
        median = float(np.median(t))
        table.row(
            env_id,
            f"{median * 1e6:.0f}",
            f"{np.percentile(t, 90) * 1e6:.0f}",
            f"{median / period:.1%}",
            f"{expert:.0f}",
            f"{random:.0f}",
            f"{expert / random:.2f}",
        )
    table = report.table(
        "The controller's time per env and step in this process: serial (one ExpertPolicy "
        "per env, called in turn) against batched (one BatchedExpert for every env), "
        f"10 alternating blocks of {args.steps} / (10 x envs) control steps each",
        [
            "env",
            "envs",
            "serial median [us]",
            "serial p90 [us]",
            "batched median [us]",
            "batched p90 [us]",
            "serial / batched",
        ],
    )
    for env_id in ENV_IDS:
        batched = batch_rows(table, env_id, args.steps)
        report.check(
            f"{env_id}: batched controller <= {GOAL_BATCHED_US:.0f} us per env at 8 envs",
            batched <= GOAL_BATCHED_US,
            f"{batched:.0f} us",
        )
    report.finish()


if __name__ == "__main__":
    main()

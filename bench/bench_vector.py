"""Vector envs against the cores: random-action steps/s, resets included.

Run: ``python bench/bench_vector.py [--json FILE]`` (options: ``--help``). For ``num_envs`` x
``num_workers``, the env steps per second of random actions (episodes end after a few
steps, so resets count) in Gymnasium's ``SyncVectorEnv`` and ``AsyncVectorEnv``, SB3's
``SubprocVecEnv`` and the batched vector env of ``ias_gym.runtime.vector_env``; each as a ratio to
one plain env (measured right before each row) and to linear scaling (``min(processes,
cores)`` x one plain env): on a machine that other processes load, no row scales. Then each
env's reset time [ms] and single-env rate, with ``IAS-PenRotate-Shadow-v0`` and
Gymnasium-Robotics' ``AdroitHandPen-v1`` (the same Shadow hand model, the same 10 ms control
period) measured in the same run and their ratio (both skipped with a message if
``gymnasium-robotics`` is missing: ``pip install -e .[hands]``). Configurations are measured
in turn, repeated, medians reported; torch runs one thread; processes start by fork.
"""

from __future__ import annotations

import argparse
import os
import time
import warnings
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
from report import Report

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.runtime.vector_env import make_batched_vec

ADROIT = "AdroitHandPen-v1"
#: The pen task on the Shadow hand (the model behind Adroit), timed beside it.
SHADOW = "IAS-PenRotate-Shadow-v0"
CONTEXT = "fork"


def _rate(step: Callable[[], int], seconds: float) -> float:
    """Env steps per second of calling ``step`` (which returns its env steps) for ``seconds``."""
    done, t0 = 0, time.perf_counter()
    while True:
        done += step()
        elapsed = time.perf_counter() - t0
        if elapsed >= seconds:
            return done / elapsed


class Single:
    """One plain env with random actions, reset when its episode ends."""

    def __init__(self, env_id: str) -> None:
        self.env = gym.make(env_id)
        self.env.reset(seed=0)
        self.env.action_space.seed(0)

    def step(self) -> int:
        _, _, te, tr, _ = self.env.step(self.env.action_space.sample())
        if te or tr:
            self.env.reset()
        return 1

    def reset_ms(self, n: int = 200) -> float:
        t0 = time.perf_counter()
        for _ in range(n):
            self.env.reset()
        return (time.perf_counter() - t0) / n * 1e3

    def close(self) -> None:
        self.env.close()


class GymVector:
    """A Gymnasium vector env (autoreset inside) with random batched actions."""

    def __init__(self, vec: Any) -> None:
        self.vec = vec
        self.vec.reset(seed=0)
        self.vec.action_space.seed(0)
        self.n = vec.num_envs

    def step(self) -> int:
        self.vec.step(self.vec.action_space.sample())
        return int(self.n)

    def close(self) -> None:
        self.vec.close()


class Sb3Vector:
    """An SB3 VecEnv (resets inside) with random batched actions."""

    def __init__(self, vec: Any) -> None:
        self.vec = vec
        self.vec.seed(0)
        self.vec.reset()
        self.space = vec.action_space
        self.space.seed(0)
        self.n = vec.num_envs

    def step(self) -> int:
        self.vec.step(np.stack([self.space.sample() for _ in range(self.n)]))
        return int(self.n)

    def close(self) -> None:
        self.vec.close()


def build(kind: str, env_id: str, n: int, workers: int) -> Any:
    """The runner of one configuration."""
    if kind == "gym sync":
        return GymVector(gym.make_vec(env_id, n, vectorization_mode="sync"))
    if kind == "gym async":
        kwargs = {"context": CONTEXT}
        return GymVector(gym.make_vec(env_id, n, vectorization_mode="async", vector_kwargs=kwargs))
    if kind == "SB3 SubprocVecEnv":
        from stable_baselines3.common.vec_env import SubprocVecEnv

        return Sb3Vector(SubprocVecEnv([lambda: gym.make(env_id)] * n, start_method=CONTEXT))
    if kind == "batched (ours)":
        return GymVector(make_batched_vec(env_id, n, workers, context=CONTEXT))
    raise ValueError(kind)


def configurations(envs: list[int], workers: list[int]) -> list[tuple[str, int, int]]:
    """(kind, num_envs, processes) in the order measured."""
    out = []
    for n in envs:
        out.append(("gym sync", n, 1))
        out.append(("gym async", n, n))
        out.append(("SB3 SubprocVecEnv", n, n))
        out += [("batched (ours)", n, w) for w in workers if w <= n]
    return out


#: The goal for our batched vector env: this fraction of linear scaling over the cores.
GOAL_LINEAR = 0.8


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    parser.add_argument("--env", default="IAS-PenSlide-v0", help="env id of the vector rows")
    parser.add_argument("--envs", default="1,2,4,8", help="num_envs values")
    parser.add_argument("--workers", default="1,2", help="num_workers values of ours")
    parser.add_argument("--seconds", type=float, default=0.5, help="per measurement [s]")
    parser.add_argument("--repeats", type=int, default=5, help="measurements per row")
    report, args = Report.start(parser)
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:
        pass
    cores = os.cpu_count() or 1
    envs = [int(v) for v in args.envs.split(",")]
    workers = [int(v) for v in args.workers.split(",")]
    report.note(f"gymnasium {gym.__version__}")

    # One plain env, the unit of the ratios, is measured right before every vector row (the
    # ratio of each pair, then the median over the repeats: load that changes between
    # rows, e.g. other processes on the machine, cancels out as far as it can).
    single = Single(args.env)
    configs = configurations(envs, workers)
    runners = {c: build(c[0], args.env, c[1], c[2]) for c in configs}
    rates: dict[tuple[str, int, int], list[float]] = {c: [] for c in configs}
    ratios: dict[tuple[str, int, int], list[float]] = {c: [] for c in configs}
    single_rates = []
    for _ in range(args.repeats):
        for c, runner in runners.items():
            base = _rate(single.step, args.seconds)
            rate = _rate(runner.step, args.seconds)
            single_rates.append(base)
            rates[c].append(rate)
            ratios[c].append(rate / base)
    for runner in runners.values():
        runner.close()
    base = float(np.median(single_rates))

    table = report.table(
        f"{args.env} in vector envs: random actions, resets included; torch on 1 thread, "
        f"processes started by fork; medians of {args.repeats} measurements of "
        f"{args.seconds:g} s per row, each right after one plain env ({base:.0f} steps/s); "
        f"/ linear = (x one env) / min(processes, envs, {cores} cores)",
        ["vector env", "envs", "processes", "random actions [steps/s]", "x one env", "/ linear"],
    )
    for c, values in rates.items():
        kind, n, procs = c
        ratio = float(np.median(ratios[c]))
        linear = min(procs, cores, n)
        table.row(
            kind,
            str(n),
            str(procs),
            f"{np.median(values):.0f}",
            f"{ratio:.2f}",
            f"{ratio / linear:.2f}",
        )
        batched = [k for k in rates if k[0] == kind]
        if kind.startswith("batched") and c == max(batched, key=lambda k: (k[1], k[2])):
            report.check(
                f"batched, {n} envs on {procs} processes: >= {GOAL_LINEAR} x linear",
                ratio / linear >= GOAL_LINEAR,
                f"{ratio / linear:.2f}",
            )

    ids = ["IAS-PenSlide-v0", "IAS-PenRotate-v0"]
    try:
        import gymnasium_robotics

        gym.register_envs(gymnasium_robotics)
        ids += [SHADOW, ADROIT]
    except ImportError:
        report.note(
            f"{SHADOW} and {ADROIT} skipped: gymnasium-robotics is not installed "
            "(pip install -e .[hands])"
        )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        singles = {e: Single(e) for e in ids}
    resets: dict[str, list[float]] = {e: [] for e in ids}
    randoms: dict[str, list[float]] = {e: [] for e in ids}
    for _ in range(args.repeats):  # in turn, so that load changes hit every row alike
        for e, s in singles.items():
            resets[e].append(s.reset_ms())
            randoms[e].append(_rate(s.step, args.seconds))
    table = report.table(
        f"One env's reset (200 in a row, no new seed) and its random actions "
        f"({args.seconds:g} s, resets included), the envs in turn, {args.repeats} times "
        "(medians)",
        ["env", "reset [ms]", "one env, random actions [steps/s]"],
    )
    for e in ids:
        table.row(e, f"{np.median(resets[e]):.3f}", f"{np.median(randoms[e]):.0f}")
        singles[e].close()
    if ADROIT in ids:  # the same hand model and engine: the pen task's wrapping against theirs
        ratio = np.median(randoms[SHADOW]) / np.median(randoms[ADROIT])
        report.note(
            f"{SHADOW} / {ADROIT} (the same hand model and engine), random-action steps/s: "
            f"{ratio:.2f} x"
        )
    single.close()
    report.finish()


if __name__ == "__main__":
    main()

"""The grip-transform controller's cost per control step, and expert vs random rollout rates.

Run: ``python bench/bench_controller.py``. For each pen task: the controller's compute per
control step (median and p90 [us], and the fraction of the 10 ms control period), then
rollout rates in env steps per second, measured side by side in the same run: the expert
(env step + controller) against uniform random actions (env step only; resets included).
"""

from __future__ import annotations

import argparse
import platform
import time

import gymnasium as gym
import mujoco
import numpy as np

import ias_gym  # noqa: F401
from ias_gym.baselines.expert import ExpertPolicy

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


def rollout_rate(env_id: str, policy: str, steps: int) -> float:
    """Env steps per second with the expert or random actions (resets included)."""
    env = gym.make(env_id)
    env.action_space.seed(0)
    expert = ExpertPolicy(env) if policy == "expert" else None
    obs, _ = env.reset(seed=0)
    t0 = time.perf_counter()
    for _ in range(steps):
        action = expert.predict(obs)[0] if expert else env.action_space.sample()
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            obs, _ = env.reset()
            if expert:
                expert.reset()
    return steps / (time.perf_counter() - t0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000, help="control steps per measurement")
    args = parser.parse_args()
    machine = platform.processor() or platform.machine()
    print(f"machine: {machine}, python {platform.python_version()}, mujoco {mujoco.__version__}")
    header = ("env", "ctrl median [us]", "p90 [us]", "of 10 ms", "expert [st/s]", "random [st/s]")
    print(f"{header[0]:<18}" + "".join(f"{h:>17}" for h in header[1:]) + f"{'ratio':>8}")
    for env_id in ENV_IDS:
        t = controller_times(env_id, args.steps)
        period = gym.make(env_id).unwrapped.config.control_dt  # type: ignore[attr-defined]
        expert = rollout_rate(env_id, "expert", args.steps)
        random = rollout_rate(env_id, "random", args.steps)
        median = float(np.median(t))
        print(
            f"{env_id:<18}{median * 1e6:>17.0f}{np.percentile(t, 90) * 1e6:>17.0f}"
            f"{median / period:>17.1%}{expert:>17.0f}{random:>17.0f}{expert / random:>8.2f}"
        )


if __name__ == "__main__":
    main()

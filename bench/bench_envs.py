"""env.step against the raw simulation it runs, for every IAS- pen environment.

Run: ``python bench/bench_envs.py [--json FILE]``. For each environment, from states of an
expert-held grasp (the contacts that make stepping expensive), time blocks of ``env.step``
and, from the same states with the same controls, blocks of the raw simulation:
``frame_skip`` calls of ``mujoco.mj_step(m, d)`` from Python ("loop"), and one
``mj_step(m, d, nstep=frame_skip)`` ("nstep", what the env calls). The table gives the
medians per step and the ratios, measured side by side in one run, then the random-action
rate (steps/s, resets included), as an RL library would see it.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from report import Report

import ias_gym  # noqa: F401
from ias_gym.baselines.grip_transform_control import GripTransformController

ENV_IDS = ("IAS-PenSlide-v0", "IAS-PenRotate-v0")


def time_env_vs_raw(env_id: str, blocks: int, block_steps: int) -> tuple[float, float, float]:
    """Median time per step [s]: env.step, raw loop of mj_step, raw nstep; same states."""
    env = gym.make(env_id)
    u: Any = env.unwrapped
    env.reset(seed=0)
    controller = GripTransformController(f0=u.config.min_grasp_force)
    for _ in range(20):
        env.step(controller.action(u))
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    start = np.empty(mujoco.mj_stateSize(u.model, spec))
    mujoco.mj_getState(u.model, u.data, start, spec)
    episode = {k: getattr(u, k) for k in u._episode_fields}
    actions = []
    for _ in range(block_steps):
        a = controller.action(u)
        actions.append(a)
        env.step(a)
    ctrl = [a * u._ctrl_max for a in actions]

    env_times, loop_times, raw_times = [], [], []
    for _ in range(blocks):
        mujoco.mj_setState(u.model, u.data, start, spec)
        for k, v in episode.items():
            setattr(u, k, v.copy() if isinstance(v, np.ndarray) else v)
        t0 = time.perf_counter()
        for a in actions:
            u.step(a)
        env_times.append((time.perf_counter() - t0) / block_steps)

        m, d, n, ids = u.model, u.data, u.frame_skip, u._act_ids
        mujoco.mj_setState(m, d, start, spec)
        t0 = time.perf_counter()
        for c in ctrl:
            d.ctrl[ids] = c
            for _ in range(n):
                mujoco.mj_step(m, d)
        loop_times.append((time.perf_counter() - t0) / block_steps)

        mujoco.mj_setState(m, d, start, spec)
        t0 = time.perf_counter()
        for c in ctrl:
            d.ctrl[ids] = c
            mujoco.mj_step(m, d, nstep=n)
        raw_times.append((time.perf_counter() - t0) / block_steps)
    return float(np.median(env_times)), float(np.median(loop_times)), float(np.median(raw_times))


def random_rate(env_id: str, steps: int) -> float:
    """Random-action env steps per second, resets included."""
    env = gym.make(env_id)
    env.reset(seed=0)
    env.action_space.seed(0)
    t0 = time.perf_counter()
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - t0)


#: The goal: an env step costs at most this much more than the physics it runs.
GOAL_RATIO = 1.15


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blocks", type=int, default=40)
    parser.add_argument("--block-steps", type=int, default=50)
    parser.add_argument("--random-steps", type=int, default=3000)
    report, args = Report.start(parser)
    table = report.table(
        f"env.step against the simulation it runs, from expert-held states, {args.blocks} "
        f"blocks of {args.block_steps} steps (medians per step); random actions over "
        f"{args.random_steps} steps, resets included",
        [
            "env",
            "env.step [us]",
            "frame_skip x `mj_step` from Python [us]",
            "`mj_step(nstep=frame_skip)` [us]",
            "env.step / loop",
            "env.step / nstep",
            "random actions [steps/s]",
        ],
    )
    for env_id in ENV_IDS:
        t_env, t_loop, t_raw = time_env_vs_raw(env_id, args.blocks, args.block_steps)
        rate = random_rate(env_id, args.random_steps)
        table.row(
            env_id,
            f"{t_env * 1e6:.0f}",
            f"{t_loop * 1e6:.0f}",
            f"{t_raw * 1e6:.0f}",
            f"{t_env / t_loop:.2f}",
            f"{t_env / t_raw:.2f}",
            f"{rate:.0f}",
        )
        report.check(
            f"{env_id}: env.step / frame_skip x mj_step <= {GOAL_RATIO}",
            t_env / t_loop <= GOAL_RATIO,
            f"{t_env / t_loop:.2f}",
        )
    report.finish()


if __name__ == "__main__":
    main()

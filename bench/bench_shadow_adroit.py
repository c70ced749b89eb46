"""The Shadow hand's pen task against Gymnasium-Robotics' AdroitHandPen-v1, side by side.

Run: ``python bench/bench_shadow_adroit.py [--json FILE]`` (needs the ``hands`` extra).
Both envs hold a pen in the Shadow hand's model on MuJoCo with a 10 ms control period: ours
(``IAS-PenRotate-Shadow-v0``) torque-drives nine joints of a fixed hand with a 2 ms physics
step; Adroit position-drives the 24 actuators of a hand on an arm with a 2 ms step. Rounds
of random-action steps (resets included, as an RL library sees them) alternate between the
two envs; the table gives the medians of the rounds and the median of the rounds' ratios
(each round's rate over the Adroit round beside it), measured in one run. A second table
times ``env.step`` alone from the same reset, beside the raw ``mj_step`` calls it makes, so
that the env's own overhead is visible.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from report import Report

import ias_gym  # noqa: F401  (registers the IAS-* ids)

OURS = "IAS-PenRotate-Shadow-v0"
ADROIT = "AdroitHandPen-v1"


def make(env_id: str) -> gym.Env[Any, Any]:
    """The env, registering Gymnasium-Robotics' ids first for Adroit."""
    if env_id == ADROIT:
        import gymnasium_robotics

        gym.register_envs(gymnasium_robotics)
    return gym.make(env_id)


def random_round(env: gym.Env[Any, Any], steps: int, seed: int) -> float:
    """Random-action steps per second over ``steps`` steps, resets included."""
    env.reset(seed=seed)
    env.action_space.seed(seed)
    actions = [env.action_space.sample() for _ in range(steps)]
    t0 = time.perf_counter()
    for a in actions:
        _, _, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - t0)


def step_vs_raw(env: gym.Env[Any, Any], steps: int) -> tuple[float, float]:
    """Median ``env.step`` and raw ``mj_step(nstep=frame_skip)`` time [s] from one reset,
    the same random controls (``steps`` steps or up to the episode's end)."""
    env.reset(seed=0)
    u = env.unwrapped
    m, d = u.model, u.data  # type: ignore[attr-defined]
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    start = np.empty(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, start, spec)
    env_times, raw_times, controls = [], [], []
    for _ in range(steps):
        t0 = time.perf_counter()
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        env_times.append(time.perf_counter() - t0)
        controls.append(d.ctrl.copy())
        if terminated or truncated:
            break
    mujoco.mj_setState(m, d, start, spec)
    for ctrl in controls:
        d.ctrl[:] = ctrl
        t0 = time.perf_counter()
        mujoco.mj_step(m, d, nstep=u.frame_skip)  # type: ignore[attr-defined]
        raw_times.append(time.perf_counter() - t0)
    return float(np.median(env_times)), float(np.median(raw_times))


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--rounds", type=int, default=15, help="alternating rounds per env")
    parser.add_argument("--steps", type=int, default=2000, help="random steps per round")
    report, args = Report.start(parser)
    envs = {env_id: make(env_id) for env_id in (OURS, ADROIT)}
    rates: dict[str, list[float]] = {env_id: [] for env_id in envs}
    for r in range(args.rounds):
        for env_id, env in envs.items():
            rates[env_id].append(random_round(env, args.steps, seed=r))
    table = report.table(
        f"{OURS} against {ADROIT}, random actions, resets included: {args.rounds} rounds of "
        f"{args.steps} steps per env, the envs alternating; medians over the rounds, and "
        "/ Adroit the median of each round's rate over the Adroit round beside it",
        ["env", "random actions [steps/s]", "min [steps/s]", "max [steps/s]", "/ Adroit"],
    )
    adroit = np.array(rates[ADROIT])
    for env_id, values in rates.items():
        ratio = float(np.median(np.array(values) / adroit))
        table.row(
            env_id,
            f"{np.median(values):.0f}",
            f"{min(values):.0f}",
            f"{max(values):.0f}",
            f"{ratio:.2f}",
        )
        if env_id == OURS:
            report.check(
                f"{OURS} random-action steps/s >= {ADROIT}'s", ratio >= 1.0, f"{ratio:.2f} x"
            )
    table = report.table(
        "env.step alone from one reset (seed 0), random actions for 400 steps or to the "
        "episode's end, beside mj_step(nstep=frame_skip) replaying its controls from the same "
        "state (medians per step)",
        ["env", "env.step [us]", "`mj_step(nstep=frame_skip)` [us]", "env.step / mj_step"],
    )
    for env_id, env in envs.items():
        t_env, t_raw = step_vs_raw(env, 400)
        table.row(env_id, f"{t_env * 1e6:.0f}", f"{t_raw * 1e6:.0f}", f"{t_env / t_raw:.2f}")
    for env in envs.values():
        env.close()
    report.finish()


if __name__ == "__main__":
    main()

"""The Shadow hand's pen task against Gymnasium-Robotics' AdroitHandPen-v1, side by side.

Run: ``python bench/bench_shadow_adroit.py`` (needs the ``hands`` extra). Both envs hold a
pen in the Shadow hand's model on MuJoCo with a 10 ms control period: ours
(``IAS-PenRotate-Shadow-v0``) torque-drives nine joints of a fixed hand with a 1 ms physics
step; Adroit position-drives the 24 actuators of a hand on an arm with a 2 ms step. Rounds
of random-action steps (resets included, as an RL library sees them) alternate between the
two envs; the table gives the medians of the rounds and the median of the rounds' ratios
(each round's rate over the Adroit round beside it), measured in one run. A second table
times ``env.step`` alone from the same reset, beside the raw ``mj_step`` calls it makes, so
that the env's own overhead is visible.
"""

from __future__ import annotations

import argparse
import platform
import time
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

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
    args = parser.parse_args()
    print(
        f"machine: {platform.processor() or platform.machine()}, python "
        f"{platform.python_version()}, mujoco {mujoco.__version__}"
    )
    envs = {env_id: make(env_id) for env_id in (OURS, ADROIT)}
    rates: dict[str, list[float]] = {env_id: [] for env_id in envs}
    for r in range(args.rounds):
        for env_id, env in envs.items():
            rates[env_id].append(random_round(env, args.steps, seed=r))
    print(f"\n{'env':<26}{'random [steps/s]':>18}{'min':>8}{'max':>8}{'/ Adroit':>10}")
    adroit = np.array(rates[ADROIT])
    for env_id, values in rates.items():
        ratio = float(np.median(np.array(values) / adroit))
        print(
            f"{env_id:<26}{np.median(values):>18.0f}{min(values):>8.0f}{max(values):>8.0f}"
            f"{ratio:>10.2f}"
        )
    print(f"\n{'env':<26}{'env.step [us]':>15}{'mj_step x frame_skip [us]':>27}{'ratio':>8}")
    for env_id, env in envs.items():
        t_env, t_raw = step_vs_raw(env, 400)
        print(f"{env_id:<26}{t_env * 1e6:>15.0f}{t_raw * 1e6:>27.0f}{t_env / t_raw:>8.2f}")
    for env in envs.values():
        env.close()


if __name__ == "__main__":
    main()

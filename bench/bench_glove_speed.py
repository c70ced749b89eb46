"""The glove world's speed: IAS-GloveGrasp-v0 steps/s and the 1 kHz CAN host loop, each
against a reference measured in the same run; optionally against a base revision, side by side.

Run: ``python bench/bench_glove_speed.py [--base REV] [--rounds 3] [--json FILE]``. Per
round, in one process per source tree (this checkout, and with ``--base`` the tree of git
revision ``REV`` extracted with ``git archive``; the trees alternate round by round):

1. *env*: random-action steps/s of ``gym.make("IAS-GloveGrasp-v0")`` (one env, resets
   included, as an RL library sees it), the median of ``--blocks`` blocks; the reference
   is the raw simulation of the same episodes: the recorded controls replayed from the
   same start states with ``mujoco.mj_step(m, d, nstep=frame_skip)`` (what the env's
   physics costs by itself). ``env/raw`` is the env's share of Python on top of it.
2. *loop*: ``ias-gym glove-bench`` at 1 kHz on the virtual bus
   (:func:`~ias_gym.hardware.bench.run_glove_bench`, ``--loop-seconds`` x ``--loop-repeats``
   runs alternating with the plain python-can loop): the host loop's rate, p99 period and
   overrun fraction, the plain loop's p99, and ``p99_ratio`` = host p99 / plain p99 (the
   goal: <= 1.15).

The table gives the medians over the rounds per tree, and with ``--base`` the ratio this
tree / base. The machine's load moves every absolute number: compare the ratios to the in-run
references (``env/raw``, ``p99_ratio``) and this tree against the base in the same run.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
ENV_ID = "IAS-GloveGrasp-v0"
GOAL_P99_RATIO = 1.15


def env_rates(blocks: int, block_steps: int) -> dict[str, float]:
    """Median steps/s of the env (random actions, resets included) and of the raw
    simulation replaying the same episodes' controls from the same start states."""
    import gymnasium as gym
    import mujoco

    import ias_gym  # noqa: F401  (registers the ids)

    env = gym.make(ENV_ID)
    u: Any = env.unwrapped
    m, d = u.model, u.data
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    env.reset(seed=0)
    env.action_space.seed(0)
    for _ in range(50):  # warm up (first-step checks, caches)
        env.step(env.action_space.sample())
    env_rate, raw_rate = [], []
    for _ in range(blocks):
        # One block: the env's steps, recording each step's start state and controls.
        starts, ctrls = [], []
        t_env = 0.0
        for _ in range(block_steps):
            state = np.empty(mujoco.mj_stateSize(m, spec))
            mujoco.mj_getState(m, d, state, spec)
            action = env.action_space.sample()
            t0 = time.perf_counter()
            _, _, terminated, truncated, _ = env.step(action)
            t_env += time.perf_counter() - t0
            starts.append(state)
            ctrls.append(d.ctrl.copy())  # the step's controls (mj_step leaves them)
            if terminated or truncated:
                t0 = time.perf_counter()
                env.reset()
                t_env += time.perf_counter() - t0
        # The raw physics of the same steps, then the env's state back as it was.
        now = np.empty(mujoco.mj_stateSize(m, spec))
        mujoco.mj_getState(m, d, now, spec)
        t_raw = 0.0
        for state, ctrl in zip(starts, ctrls, strict=True):
            mujoco.mj_setState(m, d, state, spec)
            d.ctrl[:] = ctrl
            t0 = time.perf_counter()
            mujoco.mj_step(m, d, u.frame_skip)
            t_raw += time.perf_counter() - t0
        mujoco.mj_setState(m, d, now, spec)
        mujoco.mj_forward(m, d)
        env_rate.append(block_steps / t_env)
        raw_rate.append(block_steps / t_raw)
    env.close()
    return {
        "env_steps_per_s": float(np.median(env_rate)),
        "raw_steps_per_s": float(np.median(raw_rate)),
        "env_over_raw_time": float(np.median(np.array(raw_rate) / np.array(env_rate))),
    }


def loop_stats(seconds: float, repeats: int) -> dict[str, float]:
    """The 1 kHz host loop and the plain python-can loop beside it (glove-bench)."""
    from ias_gym.hardware.bench import run_glove_bench

    result = run_glove_bench(
        channel=f"bench-speed-{os.getpid()}", rate_hz=1000.0, seconds=seconds, repeats=repeats
    )
    out = result.as_dict()
    keys = ("rate_hz", "period_p99_ms", "overrun_fraction", "step_median_ms", "plain_p99_ms")
    return {**{k: float(out[k]) for k in keys}, "p99_ratio": float(out["p99_ratio"])}


def measure(args: argparse.Namespace) -> dict[str, float]:
    """One round in this process, on whichever ``ias_gym`` it imports."""
    out = env_rates(args.blocks, args.block_steps)
    if args.loop_seconds > 0:
        out.update(loop_stats(args.loop_seconds, args.loop_repeats))
    return out


def extract(rev: str, into: Path) -> Path:
    """The source tree of git revision ``rev`` of this repository, under ``into``."""
    archive = into / "base.tar"
    subprocess.run(
        ["git", "-C", str(ROOT), "archive", "--format=tar", "-o", str(archive), rev], check=True
    )
    tree = into / "base"
    with tarfile.open(archive) as tar:
        # The "data" filter where this Python has it (3.11.4+): a plain tree, no links out.
        kwargs: dict[str, Any] = {"filter": "data"} if hasattr(tarfile, "data_filter") else {}
        tar.extractall(tree, **kwargs)
    return tree


def run_round(tree: Path, args: argparse.Namespace) -> dict[str, float]:
    """One round of :func:`measure` in a fresh process importing ``ias_gym`` from ``tree``."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    env.setdefault("MUJOCO_GL", "egl")
    cmd = [
        sys.executable,
        str(Path(__file__).resolve()),
        "--measure",
        f"--blocks={args.blocks}",
        f"--block-steps={args.block_steps}",
        f"--loop-seconds={args.loop_seconds}",
        f"--loop-repeats={args.loop_repeats}",
    ]
    done = subprocess.run(cmd, env=env, check=True, capture_output=True, text=True)
    return dict(json.loads(done.stdout.strip().splitlines()[-1]))


ROWS = (
    ("env_steps_per_s", "env, random actions [steps/s]", "{:.0f}"),
    ("raw_steps_per_s", "raw physics, the same controls (ref) [steps/s]", "{:.0f}"),
    ("env_over_raw_time", "env / raw time per step", "{:.2f}"),
    ("rate_hz", "host loop rate [Hz]", "{:.0f}"),
    ("step_median_ms", "host step median [ms]", "{:.3f}"),
    ("period_p99_ms", "host p99 period [ms]", "{:.2f}"),
    ("overrun_fraction", "host overrun fraction", "{:.3f}"),
    ("plain_p99_ms", "plain p99 period (ref) [ms]", "{:.2f}"),
    ("p99_ratio", f"p99 ratio host / plain (goal <= {GOAL_P99_RATIO})", "{:.2f}"),
)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", help="git revision to measure beside this tree")
    parser.add_argument("--rounds", type=int, default=3, help="rounds per tree (medians)")
    parser.add_argument("--blocks", type=int, default=5, help="env blocks per round")
    parser.add_argument("--block-steps", type=int, default=400, help="env steps per block")
    parser.add_argument("--loop-seconds", type=float, default=3.0, help="per loop run; 0: skip")
    parser.add_argument("--loop-repeats", type=int, default=2, help="loop runs per round")
    parser.add_argument("--measure", action="store_true", help=argparse.SUPPRESS)
    if "--measure" in sys.argv[1:]:  # one round, in a process of run_round: JSON, no report
        args = parser.parse_args()
        print(json.dumps(measure(args)))
        return 0

    # Imported here, not at the top: a --measure process imports ias_gym from the tree it
    # measures, and a base revision may predate the modules report.py imports.
    from report import Report

    report, args = Report.start(parser)
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"this": ROOT}
        if args.base:
            trees = {"base": extract(args.base, Path(tmp)), **trees}
        results: dict[str, list[dict[str, float]]] = {name: [] for name in trees}
        for r in range(args.rounds):
            for name, tree in trees.items():
                results[name].append(run_round(tree, args))
                print(f"round {r + 1}/{args.rounds} {name}: done", file=sys.stderr, flush=True)
    medians = {
        name: {k: float(np.median([run[k] for run in runs])) for k in runs[0]}
        for name, runs in results.items()
    }
    names = list(trees)
    title = (
        f"{ENV_ID} against its raw physics: {args.blocks} blocks of {args.block_steps} "
        "random-action steps (resets included) beside mj_step replaying the same controls"
    )
    if args.loop_seconds > 0:
        title += (
            f"; the 1 kHz CAN host loop beside a plain python-can loop, {args.loop_repeats} "
            f"runs of {args.loop_seconds:g} s each"
        )
    title += f"; medians over {args.rounds} rounds, each round in its own process"
    if args.base:
        title += f", this tree and base (git revision {args.base}) alternating"
    table = report.table(
        title,
        [
            f"median over {args.rounds} rounds",
            *(f"base ({args.base})" if n == "base" else "this tree" for n in names),
            *(["this / base"] if args.base else []),
        ],
    )
    for key, label, fmt in ROWS:
        if key not in medians["this"]:
            continue
        cells = [fmt.format(medians[n][key]) for n in names]
        if args.base:
            cells.append(f"{medians['this'][key] / medians['base'][key]:.2f}")
        table.row(label, *cells)
    report.finish()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

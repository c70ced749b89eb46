"""How well a tip's ratio ceiling reads the pen's friction, per hand and disturbance.

The grip-transform expert reads the pen's friction from a tip pinned on its cone (the
ceiling reading of :class:`~ias_gym.baselines.friction_estimate.FrictionEstimate`,
docs/controller.md). This script runs the first ``--sessions`` successful glove sessions of
``--db`` (development persons) on each of ``--hands`` under each of ``--disturbances``,
with the controller planning with the nominal coefficient (no reading of either kind), and
replays the measured tip forces of each run through the ceiling reading for every
``--tolerances`` x ``--steps`` (a plateau of that many control steps). For each it counts the
runs that read the pen's coefficient (within 3 %), read less (a sticking tip taken for a
cone: the squeeze would be too strong) or read more. It chose the tolerance of
``ControllerGains.plateau_tolerance`` (0.2 %: every reading within 3 % of the pen's
coefficient but one, on ias4f; 1 %: the IAS hands' sticking tips read too little);
``train/fit_gain.py --gain plateau_time`` fits the duration.
The forces replayed are the env's (``info["contact_forces"]``), without the sensor noise of
``observation_noise``; the fit runs that class through the controller's own measurement::

    python train/ceiling_readings.py --db dev1268.db --sessions 40
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ias_gym.baselines.friction_estimate import FrictionEstimate
from ias_gym.envs.pen_skill_env import PenSkillConfig
from ias_gym.errors import InputError
from ias_gym.robustness import DISTURBANCES, check_classes
from ias_gym.skills import SkillDB
from ias_gym.skills.transfer import transfer_reference
from ias_gym.skills.transfer_run import run_transfer, transfer_gains
from ias_gym.skills.workspace import hand_names


def forces(db: str, skill_id: int, hand: str, disturbance: str) -> np.ndarray:
    """The measured tip forces ``(T, 3 k)`` [N] of one run planned with the nominal mu."""
    with SkillDB(db, readonly=True) as handle:
        reference = transfer_reference(handle.get(skill_id), hand)
    gains = dataclasses.replace(transfer_gains(hand), slip_speed=float("inf"), plateau_time=0.0)
    run, _ = run_transfer(reference, hand, "gt", gains=gains, **DISTURBANCES[disturbance])
    c = np.asarray(run.contact_forces, dtype=float)
    return c.reshape(len(c), -1)


def reading(c: np.ndarray, tolerance: float, steps: int, n_min: float, dt: float) -> float:
    """The ceiling reading after a run's forces ``c`` (0: none)."""
    estimate = FrictionEstimate(duration=np.inf, plateau=steps * dt, tolerance=tolerance)
    still = np.zeros(c.shape[1] // 3, dtype=bool)
    for row in c:
        estimate.update(row, still, n_min, dt)
    return estimate.value


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--db", required=True, help="development sessions")
    ap.add_argument("--sessions", type=int, default=40, help="successful sessions run")
    ap.add_argument("--hands", default="leap,shadow,ias3f,ias4f", help="comma-separated")
    ap.add_argument(
        "--disturbances",
        default="nominal,friction_x0.7,friction_x1.3",
        help="comma-separated classes",
    )
    ap.add_argument("--tolerances", default="0.002,0.01", help="relative, comma-separated")
    ap.add_argument("--steps", default="3,5,8", help="plateau lengths [control steps]")
    args = ap.parse_args(argv)
    try:
        classes = check_classes(args.disturbances.split(","))
        hands = [h.strip() for h in args.hands.split(",")]
        unknown = sorted(set(hands) - set(hand_names()))
        if unknown:
            raise InputError(f"--hands {','.join(unknown)}: choose from {', '.join(hand_names())}")
        if not Path(args.db).is_file():
            raise InputError(f"--db {args.db} does not exist")
    except InputError as exc:
        print(f"ceiling_readings.py: error: {exc}", file=sys.stderr)
        return 2
    with SkillDB(args.db, readonly=True) as handle:
        ids = [s.id for s in handle.list_skills(success=True)][: args.sessions]
    runs: dict[tuple[str, str], list[np.ndarray]] = {}
    items = [(h, d, i) for h in hands for d in classes for i in ids]
    for hand, disturbance, skill_id in tqdm(items, desc="runs", unit="run"):
        runs.setdefault((hand, disturbance), []).append(
            forces(args.db, skill_id, hand, disturbance)
        )
    config = PenSkillConfig()
    dt, n_min, mu = config.control_dt, config.min_grasp_force, transfer_gains(hands[0]).mu
    for tolerance in (float(t) for t in args.tolerances.split(",")):
        for steps in (int(s) for s in args.steps.split(",")):
            print(f"tolerance {tolerance:g}, {steps} steps (read right / less / more of runs):")
            for (hand, disturbance), cs in runs.items():
                true = mu * DISTURBANCES[disturbance].get("friction_scale", 1.0)
                values = [reading(c, tolerance, steps, n_min, dt) for c in cs]
                read = np.array([v for v in values if v > 0])
                right = int(np.sum(np.abs(read - true) <= 0.03 * true))
                less = int(np.sum(read < 0.97 * true))
                print(
                    f"  {hand:7s} {disturbance:18s} {right} / {less} / {len(read) - right - less}"
                    f" of {len(cs)}"
                )
    return 0


if __name__ == "__main__":
    sys.exit(main())

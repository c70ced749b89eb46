"""Fit the transfer tolerances: a success test that tells a repetition from a weak execution.

    python train/transfer_table.py --build-db out/repeats.db --population 24 \\
        --population-seed S --episodes 4          # 4 sessions per person and skill class
    python train/transfer_tolerances.py --db out/repeats.db \\
        --out ias_gym/assets/transfer_tolerances.json --overwrite

Every successful glove session of ``--db`` becomes an unscaled reference
(:func:`ias_gym.skills.transfer.transfer_reference` with an unbounded workspace). Two
kinds of executions of a demonstration are measured against it with the env's own metrics
(:func:`ias_gym.skills.tolerance.reference_distance`: RMS axis angle, RMS centre distance,
mean relative margin error):

- **repetitions**, which the test must pass: every other session of the same person and
  skill class (ordered pairs);
- **weak executions**, which it must fail: the pen held still at its start pose with the
  demonstrated margin (``still``), and the demonstrated motion with a constant margin
  (``margin_1.2``, ``margin_2.0``).

Per skill class, the tracking tolerances (rotation and position) are the same quantile
``q_track`` of the repetitions' distances, and the margin tolerance the quantile
``q_margin`` of theirs; each level is the one of ``0.50, 0.51, ..., 0.99`` that separates
repetitions from the weak executions best (balanced accuracy: the mean of the share of
repetitions that pass and the share of weak executions that fail; the still pen for the
tracking, the constant margins for the margin). Cross-validated over groups of persons
(``--folds``, persons dealt round-robin): the levels are fitted on the other groups and
the held-out group's balanced accuracy is recorded per fold, with the shares of held-out
repetitions and weak executions that pass. ``"*"`` pools every class (for skills of a
class the fit never saw). The output is written atomically and refused if it exists
unless ``--overwrite``.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

#: Quantile levels tried, lowest first.
LEVELS = np.round(np.arange(0.5, 0.9951, 0.01), 2)
#: The constant margins of the weak executions [-].
WEAK_MARGINS = (1.2, 2.0)
#: Which columns of a distance row each test reads: rotation and position, margin.
TRACK, MARGIN = [0, 1], [2]


def load_groups(db_path: Path) -> dict[tuple[str, str], list[Any]]:
    """Unscaled references of every successful glove session, by (person, skill class)."""
    from ias_gym.skills.db import SkillDB
    from ias_gym.skills.tolerance import POOLED, Tolerance
    from ias_gym.skills.transfer import transfer_reference
    from ias_gym.skills.workspace import HandWorkspace

    unbounded = HandWorkspace(reach=math.inf, tilt=math.inf)
    placeholder = {POOLED: Tolerance(1.0, 1.0, 1.0)}  # what is being fitted
    groups: dict[tuple[str, str], list[Any]] = defaultdict(list)
    with SkillDB(db_path, readonly=True) as db:
        summaries = [s for s in db.list_skills(success=True) if s.person_id]
        for summary in tqdm(summaries, desc="references", unit="skill"):
            skill = db.get(summary.id)
            reference = transfer_reference(skill, workspace=unbounded, tolerances=placeholder)
            groups[(str(skill.person_id), skill.name)].append(reference)
    return groups


def pair_distances(refs: Sequence[Any]) -> np.ndarray:
    """``(pairs, 3)`` rotation [rad], position [m], margin [-] of each ordered pair."""
    from ias_gym.skills.tolerance import reference_distance

    rows = [reference_distance(a, b) for a, b in itertools.permutations(refs, 2)]
    return np.array(rows, dtype=float).reshape(-1, 3)


def passes(distances: np.ndarray, tol: np.ndarray, columns: list[int]) -> np.ndarray:
    """Which rows are within the tolerances of ``columns``."""
    return np.all(distances[:, columns] <= tol[columns], axis=1)


def balanced_accuracy(
    repeats: np.ndarray, weak: np.ndarray, tol: np.ndarray, columns: list[int]
) -> float:
    """Mean of the repetitions' pass rate and the weak executions' fail rate."""
    return 0.5 * (
        float(np.mean(passes(repeats, tol, columns)))
        + 1.0
        - float(np.mean(passes(weak, tol, columns)))
    )


def fit(repeats: np.ndarray, weak: np.ndarray, columns: list[int]) -> tuple[np.ndarray, float]:
    """The quantile level of :data:`LEVELS` (the lowest of equals) whose tolerances (3,)
    separate ``repeats`` from ``weak`` best on ``columns``, with those tolerances."""
    scored = [
        (balanced_accuracy(repeats, weak, np.quantile(repeats, q, axis=0), columns), -q)
        for q in LEVELS
    ]
    level = -max(scored)[1]
    return np.quantile(repeats, level, axis=0), float(level)


def weak_distances(refs: Sequence[Any]) -> dict[str, np.ndarray]:
    """Each demonstration's distance from the weak executions of it."""
    from ias_gym.skills.tolerance import (
        constant_margin_reference,
        reference_distance,
        still_reference,
    )

    out: dict[str, list[tuple[float, float, float]]] = defaultdict(list)
    for ref in refs:
        out["still"].append(reference_distance(still_reference(ref), ref))
        for m in WEAK_MARGINS:
            out[f"margin_{m}"].append(reference_distance(constant_margin_reference(ref, m), ref))
    return {k: np.array(v) for k, v in out.items()}


def fit_class(
    repeats: dict[Any, np.ndarray], weak: dict[Any, dict[str, np.ndarray]], keys: list[Any]
) -> tuple[np.ndarray, dict[str, float]]:
    """Fit one class's tolerances (3,) on the (person, class) groups ``keys``."""

    def stack(kind: str | None) -> np.ndarray:
        parts = [repeats[k] if kind is None else weak[k][kind] for k in keys if k in repeats]
        return np.concatenate(parts) if parts else np.zeros((0, 3))

    margins = np.concatenate([stack(f"margin_{m}") for m in WEAK_MARGINS])
    tol_track, q_track = fit(stack(None), stack("still"), TRACK)
    tol_margin, q_margin = fit(stack(None), margins, MARGIN)
    tol = np.concatenate([tol_track[TRACK], tol_margin[MARGIN]])
    return tol, {"q_track": q_track, "q_margin": q_margin}


def evaluate_class(
    repeats: dict[Any, np.ndarray],
    weak: dict[Any, dict[str, np.ndarray]],
    keys: list[Any],
    tol: np.ndarray,
) -> dict[str, float]:
    """Pass rates of ``keys``' repetitions and weak executions under ``tol``."""
    rows = [repeats[k] for k in keys if k in repeats]
    out = {"repeats": float(np.mean(passes(np.concatenate(rows), tol, [0, 1, 2])))}
    for kind in ["still", *(f"margin_{m}" for m in WEAK_MARGINS)]:
        out[kind] = float(
            np.mean(passes(np.concatenate([weak[k][kind] for k in keys]), tol, [0, 1, 2]))
        )
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Fit, cross-validate and write the tolerance file."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--db", required=True, help="repeated glove sessions of each person")
    parser.add_argument("--out", required=True, help="the tolerance JSON file")
    parser.add_argument("--overwrite", action="store_true", help="replace --out")
    parser.add_argument("--folds", type=int, default=4, help="groups of persons")
    args = parser.parse_args(argv)

    from ias_gym.envs.pen_skill_env import PenSkillConfig
    from ias_gym.outputs import atomic_output, check_output_file

    out = check_output_file(args.out, overwrite=args.overwrite, suffixes=(".json",), what="--out")
    if args.folds < 2:
        print(f"--folds must be >= 2, got {args.folds}", file=sys.stderr)
        return 2
    groups = load_groups(Path(args.db))
    persons = sorted({p for p, _ in groups})
    classes = sorted({c for _, c in groups})
    fold_of = {p: i % args.folds for i, p in enumerate(persons)}
    repeats = {key: pair_distances(refs) for key, refs in groups.items() if len(refs) >= 2}
    if not repeats:
        print(
            f"--db {args.db}: no person has two successful sessions of one skill", file=sys.stderr
        )
        return 2
    weak = {key: weak_distances(refs) for key, refs in groups.items() if key in repeats}

    entries: dict[str, Any] = {}
    for name in [*classes, "*"]:
        keys = [k for k in repeats if name in ("*", k[1])]
        tol, levels = fit_class(repeats, weak, keys)
        folds = []
        for f in range(args.folds):
            train = [k for k in keys if fold_of[k[0]] != f]
            test = [k for k in keys if fold_of[k[0]] == f]
            if not test or not train:
                continue
            fold_tol, _ = fit_class(repeats, weak, train)
            folds.append(
                {k: round(v, 4) for k, v in evaluate_class(repeats, weak, test, fold_tol).items()}
            )
        entries[name] = {
            "rot_rms_deg": math.degrees(float(tol[0])),
            "pos_rms_mm": 1000.0 * float(tol[1]),
            "margin_err_rel": float(tol[2]),
            **levels,
            "pairs": int(sum(len(repeats[k]) for k in keys)),
            "persons": len({k[0] for k in keys}),
            "pass_rate": {
                k: round(v, 4) for k, v in evaluate_class(repeats, weak, keys, tol).items()
            },
            "heldout_pass_rate_by_fold": folds,
        }
        mean = {k: float(np.mean([f[k] for f in folds])) for k in folds[0]} if folds else {}
        print(
            f"{name:>12}: rot {entries[name]['rot_rms_deg']:.2f} deg, pos "
            f"{entries[name]['pos_rms_mm']:.2f} mm, margin {tol[2]:.3f} (q {levels['q_track']:.2f}"
            f" / {levels['q_margin']:.2f}); held-out pass: "
            + ", ".join(f"{k} {v:.2f}" for k, v in mean.items())
        )
    result = {
        "what": "tolerances of the skill-transfer success test, per skill class: quantiles "
        "of the persons' repeat-to-repeat distances, the levels fitted to separate "
        "repetitions from weak executions (train/transfer_tolerances.py)",
        "db": Path(args.db).name,
        "persons": persons,
        "folds": args.folds,
        "settle_time_s": PenSkillConfig.settle_time,
        "duration_s": PenSkillConfig.duration,
        "classes": entries,
    }
    with atomic_output(out, overwrite=args.overwrite) as path:
        path.write_text(json.dumps(result, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

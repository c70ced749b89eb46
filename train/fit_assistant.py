"""Fit the observation assistant's stop test on development persons, by what it is for.

The stop test (:class:`~ias_gym.assist.policy.AssistParams`: ``stop_window_s``, the window
over which the operator's speed is compared with the fitted model's, and ``stop_ratio``, the
share below which the operator has stopped) decides when the assistant completes a skill.
Its value is judged by the sessions it produces: for persons drawn from the population with
``--seed`` (development persons: never the seed an evaluation reports), every skill with a
motion of its own is performed once unimpaired and once with ``stops:at=F`` (F drawn from
the family's sample range per person and skill), each assisted with the phase recogniser at
every grid point of ``--windows`` x ``--ratios``, and judged against the person's unimpaired,
unassisted reference (:func:`~ias_gym.assist.assistance_evaluation.reference_session`;
(person, skill) pairs without one are left out and counted).

A grid point is chosen by its success on the unimpaired sessions first (an unimpaired
operator must lose nothing to the assistant), then on the stopped ones (which only a
completion saves); ``--objective balanced`` takes the mean of the two rates instead. Folds
are groups of persons (``--folds``): each fold's grid point is chosen on the others, and the
success it gives on the fold's own persons is reported with 95 % intervals. The grid point
chosen on all persons (ties: the first in the grid's order, smaller windows and ratios
first) is written to
``ias_gym/assets/assistant_params.json`` (``--out``; an existing file only with
``--overwrite``).

    ias-gym assist library --db out/library.db --population 8 --population-seed 61
    python train/fit_assistant.py --db out/library.db --persons 16 --seed 7001 --folds 4 \
        --workers 2 --report out/fit_assistant.json --overwrite
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np

import ias_gym  # noqa: F401  (registers the envs)
from ias_gym.assist.assistance_evaluation import reference_session
from ias_gym.assist.policy import PARAMS_PATH, AssistParams, make_assistant
from ias_gym.assist.sessions import run_session, session_success
from ias_gym.assist.skill_motions import load_motions
from ias_gym.errors import InputError
from ias_gym.glove.impairment_spec import FAMILIES
from ias_gym.glove.impairments import session_rng
from ias_gym.glove.population import population_ids
from ias_gym.outputs import atomic_output, check_output_files
from ias_gym.rates import Rate
from ias_gym.runtime.jobs import Backend, run_jobs

#: The grid searched (``--windows`` [s], ``--ratios`` [-]).
WINDOWS = (0.1, 0.15)
RATIOS = (0.2, 0.3, 0.4)
#: The two kinds of session: unimpaired (0) and stopped (1).
UNIMPAIRED, STOPPED = 0, 1


@dataclass(frozen=True)
class PersonJob:
    """A picklable job: one person's sessions at every grid point.

    Returns rows ``(skill, kind, window, ratio, success)``, and ``(skill, -1, nan, nan,
    False)`` for a skill without a reference."""

    grid: tuple[tuple[float, float], ...]
    base: AssistParams
    db: str | None = None  # the skill library (None: the shipped one)

    def __call__(self, person: str) -> list[tuple[str, int, float, float, bool]]:
        rows: list[tuple[str, int, float, float, bool]] = []
        for skill in sorted(load_motions(self.db)):
            reference = reference_session(person, skill, 0)
            if reference is None:
                rows.append((skill, -1, float("nan"), float("nan"), False))
                continue
            lo, hi = (float(v) for v in FAMILIES["stops"]["at"].sample)
            at = float(session_rng("fit-stops", person, skill).uniform(lo, hi))
            for kind, spec in ((UNIMPAIRED, "none"), (STOPPED, f"stops:at={at:.3f}")):
                env = gym.make("IAS-GloveAssist-v0", person_id=person, skill=skill, impairment=spec)
                layout = env.unwrapped.observation_layout  # type: ignore[attr-defined]
                for window, ratio in self.grid:
                    params = dataclasses.replace(self.base, stop_window_s=window, stop_ratio=ratio)
                    assistant = make_assistant(
                        self.db, recogniser="phase", params=params, layout=layout
                    )
                    result = run_session(env, assistant, 0)
                    rows.append((skill, kind, window, ratio, session_success(result, reference)))
                env.close()
        return rows


def rates(outcomes: np.ndarray) -> tuple[float, float]:
    """(unimpaired, stopped) success rates of ``outcomes``, rows ``(kind, success)``; 0 for a
    kind without sessions."""
    out = [outcomes[outcomes[:, 0] == k, 1] for k in (UNIMPAIRED, STOPPED)]
    unimpaired, stopped = (float(r.mean()) if len(r) else 0.0 for r in out)
    return unimpaired, stopped


def score(outcomes: np.ndarray, objective: str) -> tuple[float, ...]:
    """What a grid point is chosen by (larger is better): ``"no-loss"``, the unimpaired
    success, then the stopped one; ``"balanced"``, their mean."""
    unimpaired, stopped = rates(outcomes)
    return (unimpaired, stopped) if objective == "no-loss" else ((unimpaired + stopped) / 2,)


def choose(
    table: dict[tuple[float, float], np.ndarray], persons: np.ndarray, objective: str
) -> tuple[float, float]:
    """The grid point with the best :func:`score` on ``persons`` (their indices, the third
    column of each point's outcomes); ties: the first in the table's order."""
    best: tuple[float, ...] = (-1.0,)
    point = next(iter(table))
    for key, outcomes in table.items():
        s = score(outcomes[np.isin(outcomes[:, 2], persons)][:, :2], objective)
        if s > best:
            best, point = s, key
    return point


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--db", help="skill library of development persons (default: the shipped one)")
    ap.add_argument("--persons", type=int, default=20, help="development persons")
    ap.add_argument("--seed", type=int, default=7001, help="population seed (development)")
    ap.add_argument("--folds", type=int, default=5, help="cross-validation groups of persons")
    ap.add_argument("--windows", default=",".join(map(str, WINDOWS)), help="stop windows [s]")
    ap.add_argument("--ratios", default=",".join(map(str, RATIOS)), help="stop ratios [-]")
    ap.add_argument(
        "--objective", choices=("no-loss", "balanced"), default="no-loss", help="what is chosen"
    )
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes")
    ap.add_argument("--out", default=str(PARAMS_PATH), help="parameter file written")
    ap.add_argument("--report", help="also write the report (JSON) here")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing --out, --report")
    args = ap.parse_args(argv)
    try:
        windows = [float(w) for w in args.windows.split(",")]
        ratios = [float(r) for r in args.ratios.split(",")]
    except ValueError:
        print("--windows and --ratios are comma-separated numbers", file=sys.stderr)
        return 2
    if not all(w > 0 for w in windows) or not all(0 < r < 1 for r in ratios):
        print("--windows must be > 0 s and --ratios in (0, 1)", file=sys.stderr)
        return 2
    if args.db is not None and not Path(args.db).is_file():
        print(f"--db {args.db} does not exist (build one: ias-gym assist library)", file=sys.stderr)
        return 2
    if args.persons < args.folds:
        print(f"--persons {args.persons} cannot fill {args.folds} folds", file=sys.stderr)
        return 2
    try:  # before any work
        outputs = check_output_files(
            {"--out": args.out, "--report": args.report}, overwrite=args.overwrite
        )
    except InputError as exc:
        print(str(exc), file=sys.stderr)
        return 2
    out, report_path = Path(args.out), outputs["--report"]
    persons = population_ids(args.persons, args.seed)
    # the defaults of what is not fitted here, never a former stop fit's values; the fields
    # train/fit_assist_field.py fits are kept from the file
    before = AssistParams.load(out) if out.is_file() else AssistParams()
    base = AssistParams(tremor_window_s=before.tremor_window_s, sight_gain=before.sight_gain)
    grid = tuple((w, r) for w in windows for r in ratios)
    per_person = run_jobs(
        PersonJob(grid, base, args.db),
        persons,
        Backend.from_options(args.workers),
        desc="persons",
        progress=True,
    )
    table: dict[tuple[float, float], list[tuple[int, bool, int]]] = {p: [] for p in grid}
    excluded = 0
    for index, rows in enumerate(per_person):
        for _skill, kind, window, ratio, success in rows:
            if kind < 0:
                excluded += 1
            else:
                table[(window, ratio)].append((kind, success, index))
    arrays = {p: np.array(v, dtype=float) for p, v in table.items()}
    folds = np.arange(len(persons)) % args.folds
    held: dict[int, list[bool]] = {UNIMPAIRED: [], STOPPED: []}
    for fold in range(args.folds):
        point = choose(arrays, np.flatnonzero(folds != fold), args.objective)
        outcomes = arrays[point]
        mine = outcomes[np.isin(outcomes[:, 2], np.flatnonzero(folds == fold))]
        for kind in held:
            held[kind] += [bool(s) for s in mine[mine[:, 0] == kind, 1]]
    window, ratio = choose(arrays, np.arange(len(persons)), args.objective)
    fitted = dataclasses.replace(
        base,
        stop_window_s=window,
        stop_ratio=ratio,
        fitted_on="; ".join(
            [
                f"{args.persons} population persons, seed {args.seed}, {args.objective}, "
                f"library {Path(args.db).name if args.db else 'shipped'}",
                *before.fitted_on.split("; ")[1:],  # the fields fitted elsewhere
            ]
        ),
    )
    fitted.save(out, overwrite=args.overwrite)
    report = {
        "stop_window_s": window,
        "stop_ratio": ratio,
        "cv_unimpaired_success": Rate.of(held[UNIMPAIRED]).to_dict(),
        "cv_stopped_success": Rate.of(held[STOPPED]).to_dict(),
        "excluded_pairs": excluded,
        "objective": args.objective,
        "grid_success_unimpaired_stopped": {
            f"{w}|{r}": rates(arrays[(w, r)][:, :2]) for w, r in grid
        },
        "sessions": [
            [persons[i], skill, kind, *((w, r) if kind >= 0 else (None, None)), ok]
            for i, rows in enumerate(per_person)
            for skill, kind, w, r, ok in rows
        ],
        "persons": args.persons,
        "seed": args.seed,
    }
    text = json.dumps(report, indent=2)
    if report_path is not None:
        with atomic_output(report_path, overwrite=args.overwrite) as tmp:
            tmp.write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

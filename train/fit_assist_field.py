"""Fit one of the observation assistant's fields on development persons, by what it is for.

Ten fields of :class:`~ias_gym.assist.motion_completion.AssistParams` are fitted this way,
each against the impairment family it is for (``--field``):

- ``tremor_window_s``: the tremor canceller (:class:`~ias_gym.assist.tremor.TremorCanceller`)
  notches the tremor band's strongest line out of the operator's targets from its first
  window on, retuned every window. A short window starts early, before the pinch closes,
  but on less of the line; a long one the other way. Judged with a tremor drawn from the
  family's sample ranges (``hz`` 4-12 Hz, ``amplitude_rad`` 0.02-0.1 rad).
- ``tremor_trend_degree``: the degree of the polynomial the canceller fits beside the
  tremor's line, the voluntary motion's part of its window. A low degree leaves the
  motion's curvature to the line (the notch then sits at the band's lowest frequency,
  away from a weak fast tremor), a high one takes up part of a slow tremor. Judged with a
  tremor drawn as for ``tremor_window_s``.
- ``catch_up_pace``: once a stop is latched (0.1-0.25 s after the operator stopped), how
  much faster than the fitted motion the completion runs until it is back on the fitted
  timeline. Slow leaves the pen behind the person's own motion; fast jerks it ahead.
  Judged with ``stops:at=F`` as for ``sight_gain``.
- ``pad_close_rate``: how fast a finger whose pad is off the pen while the other's is on is
  closed (:class:`~ias_gym.assist.pad_contact.PadKeeper`). A slow close lets the pen go in
  the lift, a fast one pushes it. Judged with a weak grip or a biased calibration (equally
  likely), ``rad`` and ``fingers`` drawn from the families' sample ranges.
- ``tremor_floor_rad``: the least amplitude of a line that the canceller takes for a
  tremor (0: no detection, the notch on every operator). A low floor notches an
  operator without a tremor too, whose voluntary motion the notch delays (a lagged
  operator's most); a high one misses a weak tremor. Judged with a tremor drawn as for
  ``tremor_window_s`` or a lag (``s`` from the family's sample range), equally likely.
- ``stop_hold_s``: how long the stop test must hold before a stop is latched (0: at the
  first window in which the operator moved less than ``stop_ratio`` of the fitted model).
  A short hold completes a stopped motion before the person's own has moved on (a fast
  motion most), a long one lets a hesitation or a turning point of an unimpaired
  operator pass. Judged with ``stops:at=F`` as for ``sight_gain``.
- ``min_remaining_rad`` and ``min_model_speed``: the stop test is armed only while the
  fitted model still has this much of its motion to go from the operator's pose and moves
  at least this fast. Low values test late in a motion and near a turning point too,
  where a person who ends a little early or slows at the turn may be taken for stopped;
  high ones leave a stop there alone. Judged with ``stops:at=F`` as for ``sight_gain``.
- ``onset_rad``: how far a joint of the skill must leave its pose at the lift's end before
  the skill's motion counts as begun (the fit reads from there, and the operator's
  unsteadiness is measured before it). A small value starts on a drift or a dip before the
  motion; a large one starts late, and misses a motion stopped early (a tilt stopped at a
  fifth of its way has moved the wrist about 0.01 rad). Judged with ``stops:at=F`` as for
  ``sight_gain``.
- ``sight_gain``: once a completed motion is done, the rate at which the assistant brings
  the pen's height to where the skill's demonstrations leave it. A slow hold leaves the
  pen where the stopped operator left it, a fast one overshoots. Judged with
  ``stops:at=F``, F drawn from the family's sample range.

Persons drawn from the population with ``--seed`` (development persons) perform every skill
once unimpaired and once with the drawn impairment (per person and skill), each assisted
(phase recogniser) at every value of ``--grid`` and judged against the person's unimpaired,
unassisted reference ((person, skill) pairs without one are left out and counted). A value
is chosen by the mean of the unimpaired and the impaired success (``--objective balanced``;
``no-loss``: the unimpaired success first, then the impaired one, so that a single
unimpaired session may decide). Folds are groups of persons, each fold's value chosen on
the others and its success on the fold's own persons reported with 95 % intervals. The
value chosen on all persons replaces the field in ``ias_gym/assets/assistant_params.json``
(``--out``, the other fields kept; ``--overwrite`` is needed, as the file exists).

    ias-gym assist library --db out/library.db --population 8 --population-seed 61
    python train/fit_assist_field.py --field tremor_window_s --db out/library.db \
        --persons 16 --seed 7001 --folds 4 --workers 2 --report out/fit.json --overwrite
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import ias_gym  # noqa: F401  (registers the envs)
from ias_gym.assist.assistance_evaluation import reference_session
from ias_gym.assist.motion_completion import PARAMS_PATH, AssistParams
from ias_gym.assist.policy import make_assistant
from ias_gym.assist.sessions import run_session, session_success
from ias_gym.errors import InputError
from ias_gym.glove.impairment_spec import FAMILIES, parse_impairment
from ias_gym.glove.impairments import session_rng
from ias_gym.glove.population import population_ids
from ias_gym.glove.skills import SKILLS
from ias_gym.outputs import atomic_output, check_output_files
from ias_gym.rates import rate_json
from ias_gym.runtime.jobs import Backend, run_jobs

#: The two kinds of session.
UNIMPAIRED, IMPAIRED = 0, 1


def drawn_tremor(person: str, skill: str) -> str:
    """The tremor spec of ``person``'s ``skill`` session: ``hz`` and ``amplitude_rad`` drawn
    uniformly from the family's sample ranges, reproducibly per person and skill."""
    rng = session_rng("fit-tremor", person, skill)
    family = FAMILIES["tremor"]
    hz_lo, hz_hi = (float(v) for v in family["hz"].sample)
    amp_lo, amp_hi = (float(v) for v in family["amplitude_rad"].sample)
    hz, amp = float(rng.uniform(hz_lo, hz_hi)), float(rng.uniform(amp_lo, amp_hi))
    return f"tremor:hz={hz:.3f},amplitude_rad={amp:.4f}"


def drawn_stop(person: str, skill: str) -> str:
    """The stop spec of ``person``'s ``skill`` session: ``at`` drawn uniformly from the
    family's sample range, reproducibly per person and skill."""
    lo, hi = (float(v) for v in FAMILIES["stops"]["at"].sample)
    return f"stops:at={float(session_rng('fit-stops', person, skill).uniform(lo, hi)):.3f}"


#: The families a detection session draws from (:func:`drawn_shake`).
SHAKE_FAMILIES = ("tremor", "lag")


def drawn_shake(person: str, skill: str) -> str:
    """The spec of ``person``'s ``skill`` session for the tremor's detection: a tremor as
    :func:`drawn_tremor` or a lag (``s`` drawn uniformly from the family's sample range,
    whose operator the notch's phase lag costs most), equally likely, reproducibly per
    person and skill."""
    rng = session_rng("fit-shake", person, skill)
    if SHAKE_FAMILIES[int(rng.integers(len(SHAKE_FAMILIES)))] == "tremor":
        return drawn_tremor(person, skill)
    lo, hi = (float(v) for v in FAMILIES["lag"]["s"].sample)
    return f"lag:s={float(rng.uniform(lo, hi)):.3f}"


#: The families a grip session draws from (:func:`drawn_grip`).
GRIP_FAMILIES = ("weak_grip", "biased_calibration")


def drawn_grip(person: str, skill: str) -> str:
    """The grip spec of ``person``'s ``skill`` session: a weak grip or a biased calibration,
    equally likely, its ``rad`` and ``fingers`` drawn uniformly from the family's sample
    ranges, reproducibly per person and skill."""
    rng = session_rng("fit-grip", person, skill)
    family = GRIP_FAMILIES[int(rng.integers(len(GRIP_FAMILIES)))]
    lo, hi = (float(v) for v in FAMILIES[family]["rad"].sample)
    fingers = tuple(str(f) for f in FAMILIES[family]["fingers"].sample)
    finger = fingers[int(rng.integers(len(fingers)))]
    return f"{family}:rad={float(rng.uniform(lo, hi)):.4f},fingers={finger}"


@dataclass(frozen=True)
class Field:
    """A fitted field: the family it is judged with (its name in the report), how a
    session's spec is drawn, the grid searched, and the families the draw picks from
    (default: ``family`` alone)."""

    family: str
    draw: Callable[[str, str], str]
    grid: tuple[float, ...]
    families: tuple[str, ...] = ()


FIELDS = {
    # from under one period of the slowest tremor to two [s]
    "tremor_window_s": Field("tremor", drawn_tremor, (0.2, 0.3, 0.4, 0.5)),
    # a straight line to a quintic: a second of voluntary motion below 2 Hz has at most 4
    # extrema, as a quintic; a higher degree reaches toward the tremor band [-]
    "tremor_trend_degree": Field("tremor", drawn_tremor, (1.0, 3.0, 5.0)),
    # from no detection (0) to the strongest line an unimpaired operator's targets show
    # (0.02 rad, measured in docs/assistance.md) [rad]
    "tremor_floor_rad": Field(
        "shake", drawn_shake, (0.0, 0.01, 0.015, 0.02), families=SHAKE_FAMILIES
    ),
    # from a latch at the first slow window (0) to a hold as long as the window itself
    # (0.1 s, the stop window's fitted length) [s]
    "stop_hold_s": Field("stops", drawn_stop, (0.0, 0.03, 0.05, 0.1)),
    # from about the spread of persons' tilts at their end (the library's amplitude spread,
    # 0.06-0.12, times a tilt's 0.18 rad) to half a tilt [rad]
    "min_remaining_rad": Field("stops", drawn_stop, (0.02, 0.035, 0.05, 0.08)),
    # from a twentieth to two fifths of a tilt's peak speed (0.18 rad in about 0.7 s, a
    # minimum-jerk peak of about 0.5 rad/s) [rad/s]
    "min_model_speed": Field("stops", drawn_stop, (0.025, 0.05, 0.1, 0.2)),
    # from five times the least unsteadiness the fit assumes (NOISE_FLOOR, 1 mrad) to twice
    # where a tilt stopped at a fifth of its way has got to (0.18 rad x 0.06) [rad]
    "onset_rad": Field("stops", drawn_stop, (0.005, 0.01, 0.02)),
    # time constants from 0.67 s down to 0.08 s, about a person's visual delay [1/s]
    "sight_gain": Field("stops", drawn_stop, (1.5, 3.0, 6.0, 12.0)),
    # from no catching up (1: the completion stays as late as the latch, 0.1-0.25 s) to
    # a fifth of the motion's remaining time [-]
    "catch_up_pace": Field("stops", drawn_stop, (1.0, 1.5, 2.0, 3.0, 5.0)),
    # from under half the speed at which the library's pinches close the index (about
    # 0.6 rad/s on its MCP) to a step's closing of 0.08 rad at 8 rad/s [rad/s]
    "pad_close_rate": Field(
        "grip", drawn_grip, (0.25, 0.5, 1.0, 2.0, 4.0, 8.0), families=GRIP_FAMILIES
    ),
}


@dataclass(frozen=True)
class PersonJob:
    """A picklable job: one person's sessions. Rows ``(spec, kind, value, success)`` with
    ``spec`` the session's impairment (``none`` unimpaired, else the drawn one); ``value``
    None for the operator alone, ``kind`` -1 for a pair without a reference."""

    field: str
    grid: tuple[float, ...]
    base: AssistParams
    db: str | None

    def __call__(self, person: str) -> list[tuple[str, int, float | None, bool]]:
        rows: list[tuple[str, int, float | None, bool]] = []
        for skill in SKILLS:
            drawn = FIELDS[self.field].draw(person, skill)
            reference = reference_session(person, skill, 0)
            if reference is None:
                rows.append((drawn, -1, None, False))
                continue
            for kind, spec in ((UNIMPAIRED, "none"), (IMPAIRED, drawn)):
                env = gym.make("IAS-GloveAssist-v0", person_id=person, skill=skill, impairment=spec)
                layout = env.unwrapped.observation_layout  # type: ignore[attr-defined]
                if kind == IMPAIRED:
                    alone = run_session(env, None, 0)
                    rows.append((spec, kind, None, session_success(alone, reference)))
                for value in self.grid:
                    changes: dict[str, Any] = {self.field: field_value(self.field, value)}
                    params = dataclasses.replace(self.base, **changes)
                    assistant = make_assistant(self.db, "phase", params=params, layout=layout)
                    result = run_session(env, assistant, 0)
                    rows.append((spec, kind, value, session_success(result, reference)))
                env.close()
        return rows


def field_value(field: str, value: float) -> float | int:
    """``value`` as ``field``'s type (an integer field takes a whole number only).

    Raises:
        InputError: ``value`` is no whole number for an integer field.
    """
    if field not in AssistParams.integer_fields():
        return value
    if value != round(value):
        raise InputError(f"--grid {value:g}: {field} takes whole numbers")
    return round(value)


def choose(
    outcomes: dict[float, list[tuple[int, bool, int]]], persons: set[int], objective: str
) -> float:
    """The value with the best score on ``persons`` (indices): ``"balanced"``, the mean of
    the unimpaired and the impaired success; ``"no-loss"``, the unimpaired success, then the
    impaired one. Ties: the first in the grid's order."""

    def score(rows: list[tuple[int, bool, int]]) -> tuple[float, ...]:
        mine = [(k, float(s)) for k, s, p in rows if p in persons]
        unimpaired, impaired = (
            [s for k, s in mine if k == kind] for kind in (UNIMPAIRED, IMPAIRED)
        )
        rates = float(np.mean(unimpaired or [0.0])), float(np.mean(impaired or [0.0]))
        return rates if objective == "no-loss" else (sum(rates) / 2,)

    return max(outcomes, key=lambda w: score(outcomes[w]))


def fitted_on(record: str, field: str, what: str) -> str:
    """``record`` (an :class:`AssistParams`' ``fitted_on``: ``"stop test; field: what; ..."``)
    with ``field``'s part replaced by ``what``."""
    parts = [p for p in record.split("; ") if not p.startswith(f"{field}:")]
    return "; ".join([*parts, f"{field}: {what}"])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--field", choices=tuple(FIELDS), required=True, help="the field fitted")
    ap.add_argument("--db", help="skill library of development persons (default: the shipped one)")
    ap.add_argument("--persons", type=int, default=16, help="development persons")
    ap.add_argument("--seed", type=int, required=True, help="their population seed")
    ap.add_argument("--folds", type=int, default=4, help="cross-validation groups of persons")
    ap.add_argument("--grid", help="values searched, comma-separated (default: the field's)")
    ap.add_argument(
        "--objective", choices=("balanced", "no-loss"), default="balanced", help="what is chosen"
    )
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes")
    ap.add_argument("--out", default=str(PARAMS_PATH), help="parameter file updated")
    ap.add_argument("--report", required=True, help="JSON report written")
    ap.add_argument("--overwrite", action="store_true", help="replace --out and --report")
    args = ap.parse_args(argv)
    field = FIELDS[args.field]
    try:
        grid = tuple(float(w) for w in args.grid.split(",")) if args.grid else field.grid
    except ValueError:
        grid = ()
    least = 0.0 if args.field in AssistParams.may_be_zero() else None
    if not grid or not all(w > 0 or w == least for w in grid):
        sign = ">= 0" if least is not None else "> 0"
        print(f"--grid {args.grid} must be comma-separated numbers {sign}", file=sys.stderr)
        return 2
    try:
        if args.db is not None and not Path(args.db).is_file():
            raise InputError(f"--db {args.db} does not exist (build one: ias-gym assist library)")
        for w in grid:
            field_value(args.field, w)
        if args.persons < args.folds:
            raise InputError(f"--persons {args.persons} cannot fill {args.folds} folds")
        check_output_files({"--report": args.report, "--out": args.out}, overwrite=args.overwrite)
        report, out = Path(args.report), Path(args.out)
        base = AssistParams.load(out)
    except InputError as exc:
        print(str(exc), file=sys.stderr)
        return 2
    persons = population_ids(args.persons, args.seed)
    per_person = run_jobs(
        PersonJob(args.field, grid, base, args.db),
        persons,
        Backend.from_options(args.workers),
        desc="persons",
        progress=True,
    )
    outcomes: dict[float, list[tuple[int, bool, int]]] = {w: [] for w in grid}
    # each value's impaired sessions by the family they drew (a field judged with several)
    by_family: dict[float, dict[str, list[bool]]] = {w: {} for w in grid}
    alone: list[bool] = []
    excluded = 0
    for index, rows in enumerate(per_person):
        for spec, kind, value, success in rows:
            if kind < 0:
                excluded += 1
            elif value is None:
                alone.append(success)
            else:
                outcomes[value].append((kind, success, index))
                if kind == IMPAIRED:
                    family = parse_impairment(spec).name
                    by_family[value].setdefault(family, []).append(success)
    folds = np.arange(len(persons)) % args.folds
    held: dict[int, list[bool]] = {UNIMPAIRED: [], IMPAIRED: []}
    for fold in range(args.folds):
        value = choose(outcomes, {int(i) for i in np.flatnonzero(folds != fold)}, args.objective)
        for kind, success, index in outcomes[value]:
            if folds[index] == fold:
                held[kind].append(success)
    chosen = choose(outcomes, set(range(len(persons))), args.objective)
    change: dict[str, Any] = {args.field: field_value(args.field, chosen)}
    fitted = dataclasses.replace(
        base,
        **change,
        fitted_on=fitted_on(
            base.fitted_on, args.field, f"{args.persons} persons, seed {args.seed}"
        ),
    )
    summary = {
        "set": "development",
        "persons": args.persons,
        "population_seed": args.seed,
        "objective": args.objective,
        args.field: chosen,
        "left_out": excluded,
        f"alone_{field.family}": rate_json(alone),
        "cross_validated": {
            "unimpaired": rate_json(held[UNIMPAIRED]),
            field.family: rate_json(held[IMPAIRED]),
        },
        "grid": {
            str(w): {
                **{
                    name: rate_json([s for k, s, _ in rows if k == kind])
                    for name, kind in (("unimpaired", UNIMPAIRED), (field.family, IMPAIRED))
                },
                **(
                    {"by_family": {f: rate_json(v) for f, v in sorted(by_family[w].items())}}
                    if len(field.families) > 1
                    else {}
                ),
            }
            for w, rows in outcomes.items()
        },
        "sessions": {str(w): rows for w, rows in outcomes.items()},
    }
    with atomic_output(report, overwrite=args.overwrite) as tmp:
        tmp.write_text(json.dumps(summary, indent=2) + "\n")
    fitted.save(out, overwrite=args.overwrite)
    print(json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

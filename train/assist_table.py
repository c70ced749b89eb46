"""The analytic assistant on population persons: success per impairment, intervention, latency.

For every impairment (``IAS-GloveAssist-v0``) and each of ``--persons`` persons drawn with
``--population-seed`` (``--set``: development or held-out data), each glove skill once
(seed ``--seed + i``) without an assistant, with the analytic assistant and, if
``--residual`` names a trained model (``train/assist_residual.py``), with the learned
residual on top of it; every session judged against the unimpaired session of the same
person, skill and seed (``ias_gym.assist.sessions``). Then the intent-switch latency:
the unimpaired operator switches skills at ``--switch-time``. Writes a markdown table, the
JSON of the numbers and, per session, what it did (``OUT.sessions.json``: success, the pose
errors, whether and when the pen was lost; ``ias_gym.assist.sessions.session_record``).

    ias-gym assist library --db out/library.db --population 8 --population-seed 61
    PYTHONPATH=$PWD python train/assist_table.py --db out/library.db --recogniser phase \
        --persons 30 --population-seed S --set held-out --out out/table_phase

``--operator script`` runs the open-loop script instead of the person in the loop.

The analytic assistant reads the env's state (docs/assistance.md), not only its observation:
it is a reference of what such help can do, not an assistant of the hardware path.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ias_gym.assist.assistance_evaluation import (
    ImpairmentScore,
    evaluate_assistance,
    switch_latency,
)
from ias_gym.assist.assistants import AnalyticAssistant
from ias_gym.assist.intent_switches import SWITCH_PAIRS, SWITCH_TIME
from ias_gym.assist.skill_templates import load_templates
from ias_gym.errors import InputError
from ias_gym.glove.impairments import DEFAULT_STRENGTHS, IMPAIRMENTS
from ias_gym.glove.operator import OPERATORS
from ias_gym.glove.population import population_ids
from ias_gym.glove.skills import SKILLS
from ias_gym.outputs import atomic_output
from ias_gym.rates import SET_KINDS
from ias_gym.runtime.jobs import Backend, run_jobs


def _seconds(value: float | None) -> str:
    """A latency for the Markdown table: two decimals, or "-" when no switch was followed."""
    return "-" if value is None else f"{value:.2f} s"


def assistant_names(recogniser: str, residual: str | None, wanted: list[str]) -> list[str]:
    """The assistants a table measures: the analytic one (``analytic``, or
    ``analytic+RECOGNISER`` with a recogniser other than the oracle) and, with a trained
    ``residual``, ``residual``; those of them ``wanted`` names."""
    names = ["analytic" if recogniser == "oracle" else f"analytic+{recogniser}"]
    if residual:
        names.append("residual")
    return [n for n in names if n.split("+")[0] in wanted]


def make_assistants(
    db: str | None, recogniser: str, residual: str | None, names: tuple[str, ...]
) -> dict[str, Any]:
    """``{name: () -> assistant}`` for :func:`assistant_names`' ``names``."""
    templates = load_templates(db)
    analytic: Any = lambda: AnalyticAssistant(templates)  # noqa: E731
    if recogniser != "oracle":
        from ias_gym.assist.recogniser_registry import make_recogniser
        from ias_gym.skills import SkillDB
        from ias_gym.skills.transfer import shipped_skill_db

        with SkillDB(db or shipped_skill_db(), readonly=True) as handle:
            rec = make_recogniser(recogniser, handle)
        analytic = lambda: AnalyticAssistant(templates, rec)  # noqa: E731
    out: dict[str, Any] = {}
    for name in names:
        if name == "residual":
            from ias_gym.learning.assist_residual import ResidualAssistant

            out[name] = lambda: ResidualAssistant.load(str(residual), templates)
        else:
            out[name] = analytic
    return out


@dataclass(frozen=True)
class PersonJob:
    """A picklable job: one person's sessions of every impairment and skill, and their
    intent switches, for each assistant. Returns ``({name: {impairment: score}},
    {name: latencies})``."""

    db: str | None
    recogniser: str
    residual: str | None
    names: tuple[str, ...]
    impairments: tuple[str, ...]
    seed: int
    strength: float | None
    operator: str
    switch_time: float

    def __call__(
        self, person: str
    ) -> tuple[dict[str, dict[str, ImpairmentScore]], dict[str, list[float]]]:
        assistants = make_assistants(self.db, self.recogniser, self.residual, self.names)
        scores, latencies = {}, {}
        for name, make in assistants.items():
            scores[name] = evaluate_assistance(
                make,
                [person],
                list(self.impairments),
                len(SKILLS),
                self.seed,
                env_kwargs=None if self.strength is None else {"strength": self.strength},
                operator=self.operator,
            )
            latencies[name] = switch_latency(
                make, [person], list(SWITCH_PAIRS), self.switch_time, self.seed, self.operator
            )
        return scores, latencies


def main(argv: list[str] | None = None) -> int:
    """Run the measurement (arguments: ``--help``)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--persons", type=int, default=30, help="population persons")
    parser.add_argument(
        "--population-seed", type=int, required=True, help="seed of the persons' draw"
    )
    parser.add_argument(
        "--set", choices=SET_KINDS, required=True, help="development or held-out persons"
    )
    parser.add_argument("--impairments", default="all", help="names or all")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--db", default=None, help="skill library (default: shipped)")
    parser.add_argument("--residual", default=None, help="a trained residual assistant (.zip)")
    parser.add_argument(
        "--assistants",
        default="analytic,residual",
        help="which to measure (residual needs --residual)",
    )
    parser.add_argument("--recogniser", default="oracle", help="oracle, dtw or phase")
    parser.add_argument("--strength", type=float, default=None, help="override (one impairment)")
    parser.add_argument("--switch-time", type=float, default=SWITCH_TIME, help="episode time [s]")
    parser.add_argument(
        "--operator",
        choices=OPERATORS,
        default="closed_loop",
        help="the simulated person: in the loop, or the open script",
    )
    parser.add_argument(
        "--out", default="out/assist_table", help="writes OUT.md, OUT.json, OUT.sessions.json"
    )
    parser.add_argument(
        "--workers", type=int, default=os.cpu_count() or 1, help="processes (persons in each)"
    )
    parser.add_argument("--overwrite", action="store_true")
    args = parser.parse_args(argv)
    out = Path(args.out)
    for suffix in (".md", ".json", ".sessions.json"):
        if out.with_suffix(suffix).exists() and not args.overwrite:
            print(f"{out.with_suffix(suffix)} exists (--overwrite)", file=sys.stderr)
            return 2
    try:
        persons = population_ids(args.persons, args.population_seed)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    out.parent.mkdir(parents=True, exist_ok=True)
    imps = list(IMPAIRMENTS) if args.impairments == "all" else args.impairments.split(",")
    names = assistant_names(args.recogniser, args.residual, args.assistants.split(","))
    results: dict[str, Any] = {
        "set": args.set,
        "population": [args.persons, args.population_seed],
        "persons": persons,
        "skills": list(SKILLS),
        "seed": args.seed,
        "operator": args.operator,
    }
    job = PersonJob(
        args.db,
        args.recogniser,
        args.residual,
        tuple(names),
        tuple(imps),
        args.seed,
        args.strength,
        args.operator,
        args.switch_time,
    )
    parts = run_jobs(
        job, persons, Backend.from_options(args.workers), desc="persons", progress=True
    )
    sessions: dict[str, Any] = {}
    latency: dict[str, Any] = {}
    for name in names:
        scores = {
            imp: ImpairmentScore.merge([scores[name][imp] for scores, _ in parts]) for imp in imps
        }
        results[name] = {k: v.to_json() for k, v in scores.items()}
        sessions[name] = {k: v.records for k, v in scores.items()}
        values = [v for _, latencies in parts for v in latencies[name]]
        finite = [v for v in values if math.isfinite(v)]
        latency[name] = {
            "median_s": float(np.median(finite)) if finite else None,
            "max_s": float(max(finite)) if finite else None,
            "never": len(values) - len(finite),
            "n": len(values),
        }
    results["switch_latency"] = latency
    lines = [
        f"{len(persons)} persons of population seed {args.population_seed} ({args.set}); "
        f"each of the {len(SKILLS)} skills once "
        f"(seeds {args.seed}-{args.seed + len(SKILLS) - 1}).",
        "",
        "| impairment | strength | unassisted | "
        + " | ".join(f"{n} | {n} intervention" for n in names)
        + " |",
        "|---|---|---|" + "---|---|" * len(names),
    ]
    for imp in imps:
        first = names[0]
        row = [
            imp,
            f"{DEFAULT_STRENGTHS[imp] if args.strength is None else args.strength:g}",
            f"{100 * results[first][imp]['success_unassisted']:.0f} %"
            f" ({results[first][imp]['sessions']})",
        ]
        for n in names:
            r = results[n][imp]
            row += [f"{100 * r['success_assisted']:.0f} %", f"{r['intervention']:.3f}"]
        lines.append("| " + " | ".join(row) + " |")
    lines += [
        "",
        "Intent-switch latency (unimpaired operator, switch at "
        f"{args.switch_time} s): "
        + "; ".join(
            f"{n}: median {_seconds(v['median_s'])}, max {_seconds(v['max_s'])}, "
            f"never {v['never']} of {v['n']}"
            for n, v in latency.items()
        ),
    ]
    text = "\n".join(lines) + "\n"
    for suffix, content in (
        (".md", text),
        (".json", json.dumps(results, indent=1)),
        (".sessions.json", json.dumps(sessions, indent=1)),
    ):
        with atomic_output(out.with_suffix(suffix), overwrite=True) as tmp:
            tmp.write_text(content)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

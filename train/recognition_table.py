"""Intent recognition on persons drawn from the population: DTW vs the phase model, and on-line
acquisition.

Records (once; reused when the databases exist) a library of glove sessions of
``--library-persons`` development persons (drawn with ``--library-seed``) and one session per
skill of ``--persons`` evaluation persons (drawn with ``--population-seed``; say with ``--set``
whether the method was tuned on them), evaluates both recognisers side by side
(:mod:`ias_gym.assist.metrics`), records each evaluation person switching between the skills
of :data:`~ias_gym.assist.intent_switches.SWITCH_PAIRS` at ``--switch-time`` and measures
how the recognisers follow them (:mod:`ias_gym.assist.intent_switches`), measures how many
demonstrations of a skill the library did not know it takes to recognise it after on-line
acquisition, and writes a markdown table, a
JSON (the rates with their 95 % Wilson intervals) and a plot (accuracy vs the observed
fraction of the skill's motion).

    python train/recognition_table.py --persons 30 --population-seed S --set held-out \\
        --out out/recognition --plot docs/img/recognition.png
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from ias_gym.assist.intent_switches import (
    SWITCH_PAIRS,
    SWITCH_TIME,
    evaluate_switches,
    record_switch_sessions,
)
from ias_gym.assist.metrics import (
    FRACTIONS,
    LabelledSession,
    evaluate_methods,
    labelled_session,
    record_sessions,
)
from ias_gym.assist.recogniser_registry import METHODS, make_recogniser
from ias_gym.assist.recognition import UNKNOWN, acquire_skill
from ias_gym.errors import InputError
from ias_gym.glove.population import population_ids
from ias_gym.glove.skills import SKILLS
from ias_gym.rates import SET_KINDS, Rate
from ias_gym.skills import Skill, SkillDB

#: The library's development persons: this many, drawn with this seed (the library the
#: recognisers are built from, and the demonstrations of the acquisition curve).
LIBRARY_PERSONS = 8
LIBRARY_SEED = 61
KEYS = (
    "recog_acc_at_33",
    "recog_acc_at_60",
    "time_to_recognise_s",
    "false_trigger_rate",
    "unknown_auroc",
    "final_accuracy",
    "unknown_detected_rate",
    "known_as_unknown_rate",
    "switches_followed",
    "switch_latency_s",
)


def sessions_of(
    path: Path, persons: list[str], episodes: int, seed: int
) -> tuple[list[Skill], list[LabelledSession]]:
    """The skills stored in ``path`` and their labelled sessions, recorded there first if the
    file does not exist."""
    if not path.exists():
        with SkillDB(path) as db:
            record_sessions(persons, SKILLS, episodes, seed=seed, db=db, progress=tqdm)
    with SkillDB(path, readonly=True) as db:
        skills = [db.get(i) for i in db.ids()]
    sessions = [labelled_session(s) for s in skills]
    found = {s.person_id for s in sessions}
    if found != set(persons) or len(sessions) != len(persons) * len(SKILLS) * episodes:
        raise InputError(
            f"{path} holds {len(sessions)} sessions of {sorted(found)}, not {episodes} per "
            f"skill of {list(persons)}; delete it to record it again"
        )
    return skills, sessions


def acquisition_curve(
    method: str,
    library_skills: list[Skill],
    library: list[LabelledSession],
    held_out: list[LabelledSession],
    demos: int,
) -> dict[str, Any]:
    """Each skill in turn left out, then demonstrated ``demos`` times (one per development
    person); after every demonstration, the held-out sessions of it and of the known skills
    are scored.

    A demonstration that ends ``unknown`` is stored as the new skill (first time: a new name;
    later: more sessions of it), as is one already recognised as it; one taken for another
    known skill is not added.
    """
    acc_new = np.zeros((len(SKILLS), demos))
    acc_known = np.zeros((len(SKILLS), demos))
    triggered = np.zeros(len(SKILLS))
    for k, skill in enumerate(tqdm(SKILLS, desc=f"acquisition {method}")):
        rec = make_recogniser(method, [s.library() for s in library if s.skill != skill])
        by_person: dict[str, tuple[Skill, LabelledSession]] = {}
        for stored, s in zip(library_skills, library, strict=True):
            if s.skill == skill:
                by_person.setdefault(s.person_id, (stored, s))  # the first of each person
        name = f"new_{skill}"
        acquired = False
        with tempfile.TemporaryDirectory() as tmp, SkillDB(Path(tmp) / "acq.db") as db:
            for n, person in enumerate(list(by_person)[:demos]):
                stored, demo = by_person[person]
                post, _ = rec.score_session(demo.frames)
                if post.best == UNKNOWN and not acquired:
                    acquire_skill(db, rec, stored, demo.frames, name)
                    acquired = True
                    triggered[k] = n + 1
                elif acquired and post.best in (UNKNOWN, name):
                    acquire_skill(db, rec, stored, demo.frames, name)
                tests = [s for s in held_out if s.skill == skill]
                known = [s for s in held_out if s.skill != skill]
                acc_new[k, n] = np.mean(
                    [rec.score_session(s.frames)[0].best == name for s in tests]
                )
                acc_known[k, n] = np.mean(
                    [rec.score_session(s.frames)[0].best == s.skill for s in known]
                )
    return {
        "demos": list(range(1, demos + 1)),
        "new_skill_accuracy": acc_new.mean(axis=0).tolist(),
        "known_skill_accuracy": acc_known.mean(axis=0).tolist(),
        "new_skill_accuracy_by_skill": {s: acc_new[k].tolist() for k, s in enumerate(SKILLS)},
        "acquired_at_demo": {s: int(triggered[k]) for k, s in enumerate(SKILLS)},
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    parser.add_argument("--persons", type=int, default=30, help="evaluation persons drawn")
    parser.add_argument(
        "--population-seed", type=int, required=True, help="seed of the evaluation persons' draw"
    )
    parser.add_argument(
        "--set", choices=SET_KINDS, required=True, help="development or held-out evaluation persons"
    )
    parser.add_argument("--library-persons", type=int, default=LIBRARY_PERSONS)
    parser.add_argument("--library-seed", type=int, default=LIBRARY_SEED)
    parser.add_argument("--library-episodes", type=int, default=2, help="sessions per skill")
    parser.add_argument("--episodes", type=int, default=1, help="evaluation sessions per skill")
    parser.add_argument("--demos", type=int, default=5, help="acquisition demonstrations")
    parser.add_argument(
        "--switch-time", type=float, default=SWITCH_TIME, help="intent switches' time [s]"
    )
    parser.add_argument("--out", default="out/recognition", help="output and cache folder")
    parser.add_argument("--plot", default="docs/img/recognition.png", help="the figure")
    parser.add_argument("--overwrite", action="store_true", help="replace existing outputs")
    parser.add_argument(
        "--replot", action="store_true", help="only redraw the plot from the JSON in --out"
    )
    args = parser.parse_args(argv)
    out = Path(args.out)
    if args.replot:
        payload = json.loads((out / "recognition.json").read_text())
        _plot(payload["methods"], payload["acquisition"], Path(args.plot))
        return 0
    if args.demos > args.library_persons:
        print(
            "error: --demos cannot exceed --library-persons (one demonstration each)",
            file=sys.stderr,
        )
        return 2
    out.mkdir(parents=True, exist_ok=True)
    outputs = [out / "recognition.md", out / "recognition.json", Path(args.plot)]
    existing = [str(p) for p in outputs if p.exists()]
    if existing and not args.overwrite:
        print(f"error: {', '.join(existing)} exist; pass --overwrite", file=sys.stderr)
        return 2
    library_ids = population_ids(args.library_persons, args.library_seed)
    ids = population_ids(args.persons, args.population_seed)
    lib_path = out / f"library_{args.library_persons}_{args.library_seed}.db"
    ho_path = out / f"persons_{args.persons}_{args.population_seed}.db"
    library_skills, library = sessions_of(lib_path, library_ids, args.library_episodes, seed=0)
    # the library learns a skill from the sessions that did it (as load_library does); the
    # evaluation counts every session
    kept = [i for i, k in enumerate(library_skills) if k.is_success]
    library_skills = [library_skills[i] for i in kept]
    library = [library[i] for i in kept]
    _, held_out = sessions_of(ho_path, ids, args.episodes, seed=1000)
    methods = list(METHODS)
    library_sessions = [s.library() for s in library]
    results = evaluate_methods(library_sessions, held_out, methods, progress=tqdm)
    switch_jobs = [(p, a, b, args.switch_time) for p in ids for a, b in SWITCH_PAIRS]
    switches = record_switch_sessions(switch_jobs, seed=1000, progress=tqdm)
    latencies = {}
    for m in methods:
        followed = evaluate_switches(make_recogniser(m, library_sessions), switches)
        latencies[m] = followed.pop("switch_latencies_s")
        results[m]["rates"].update(followed.pop("rates"))
        results[m].update(followed)
    acquisition = {
        m: acquisition_curve(m, library_skills, library, held_out, args.demos) for m in methods
    }
    payload = {
        "set": args.set,
        "population_seed": args.population_seed,
        "persons": len(ids),
        "library_seed": args.library_seed,
        "library_persons": len(library_ids),
        "library_sessions": len(library),
        "held_out_sessions": len(held_out),
        "methods": results,
        "switch_time_s": args.switch_time,
        "switch_pairs": [list(pair) for pair in SWITCH_PAIRS],
        "switch_latencies_s": latencies,
        "acquisition": acquisition,
    }
    (out / "recognition.json").write_text(json.dumps(payload, indent=2))
    lines = [
        f"Library: {len(library)} sessions of {len(library_ids)} development persons "
        f"(population seed {args.library_seed}); evaluated on {len(held_out)} sessions of "
        f"{len(ids)} persons (population seed {args.population_seed}, {args.set}).",
        "",
        "| method | " + " | ".join(KEYS) + " |",
        "|---|" + "---|" * len(KEYS),
    ]
    for m in methods:
        cells = ["-" if results[m][k] is None else f"{results[m][k]:.3f}" for k in KEYS]
        lines.append(f"| {m} | " + " | ".join(cells) + " |")
    lines += ["", "With 95 % Wilson intervals:", ""]
    for m in methods:
        for key, row in results[m]["rates"].items():
            lines.append(f"- {m} {key}: {Rate(row['successes'], row['trials'])}")
    lines += ["", "Accuracy by observed fraction of the skill's motion:", ""]
    lines.append("| method | " + " | ".join(f"{f:.0%}" for f in FRACTIONS) + " |")
    lines.append("|---|" + "---|" * len(FRACTIONS))
    for m in methods:
        curve = results[m]["accuracy_by_fraction"]
        lines.append(f"| {m} | " + " | ".join(f"{curve[f'{f:.1f}']:.2f}" for f in FRACTIONS) + " |")
    lines += ["", "On-line acquisition: accuracy on held-out sessions after n demonstrations:", ""]
    lines.append(
        "| method | skill | " + " | ".join(f"n={n}" for n in range(1, args.demos + 1)) + " |"
    )
    lines.append("|---|---|" + "---|" * args.demos)
    for m in methods:
        a = acquisition[m]
        lines.append(
            f"| {m} | new (mean) | "
            + " | ".join(f"{v:.2f}" for v in a["new_skill_accuracy"])
            + " |"
        )
        lines.append(
            f"| {m} | known (mean) | "
            + " | ".join(f"{v:.2f}" for v in a["known_skill_accuracy"])
            + " |"
        )
    (out / "recognition.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    _plot(results, acquisition, Path(args.plot))
    return 0


def _plot(results: dict[str, Any], acquisition: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 3.8))
    colour = {m: f"C{i}" for i, m in enumerate(results)}
    for m, r in results.items():
        curve = r["accuracy_by_fraction"]
        ax.plot(
            [100 * f for f in FRACTIONS],
            [curve[f"{f:.1f}"] for f in FRACTIONS],
            "o-",
            color=colour[m],
            label=m,
        )
    ax.axhline(0.7, color="grey", ls=":", lw=1)
    ax.axhline(0.95, color="grey", ls=":", lw=1)
    ax.set_xlabel("observed fraction of the skill's motion [%]")
    ax.set_ylabel("accuracy (held-out persons)")
    ax.set_ylim(0, 1.02)
    ax.legend()
    ax.set_title("intent recognition")
    for m, a in acquisition.items():
        bx.plot(a["demos"], a["new_skill_accuracy"], "o-", color=colour[m], label=f"{m}: new skill")
        bx.plot(
            a["demos"],
            a["known_skill_accuracy"],
            "s--",
            color=colour[m],
            alpha=0.5,
            label=f"{m}: known skills",
        )
    bx.set_xticks(list(acquisition[next(iter(acquisition))]["demos"]))
    bx.axhline(0.9, color="grey", ls=":", lw=1)
    bx.set_xlabel("demonstrations of the new skill")
    bx.set_ylabel("accuracy (held-out persons)")
    bx.set_ylim(0, 1.02)
    bx.legend(fontsize=8)
    bx.set_title("on-line acquisition")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    raise SystemExit(main())

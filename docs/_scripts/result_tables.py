"""The results tables of the docs, written at build time from the result JSON files.

Each results page includes a table from ``docs/_generated/`` (not committed) that this
script writes from the JSON file that the script measuring it left in ``docs/``, so a page
shows the numbers of the latest run:

=====================================  ==================================  =================
JSON in ``docs/``                      written by                          table
=====================================  ==================================  =================
``transfer_results.json``              ``train/transfer_table.py``         ``transfer.md``,
                                                                           ``transfer_skills.md``
``hand_reach.json``                    ``train/hand_reach.py``             ``hand_reach.md``
``recognition_results.json``           ``train/recognition_table.py``      ``recognition.md``
``assist_table_phase.json``,           ``train/assist_table.py``           ``assistance.md``
``assist_table_residual.json``
``assist_population.json``             ``train/assist_population.py``      ``assist_population.md``
``assist_residual_population.json``    ``train/assist_population.py``      ``assist_residual_``
                                       ``--residual``                      ``population.md``
``assist_pads_population.json``        ``train/assist_population.py``      ``assist_pads_``
                                       ``--without pads``                  ``population.md``
``assist_trend_population.json``       ``train/assist_population.py``      ``assist_trend_``
                                       ``--without tremor``                ``population.md``
the draws of ``ASSIST_DRAWS``          ``train/assist_population.py``      ``assist_draws.md``,
                                       ``--sessions``                      ``assist_latest_``
                                                                           ``draw.md`` (the last)
``assist_acquisition.json``            ``train/assist_acquisition.py``     ``assist_acquisition.md``
``pen_skill_bc_results.json``          ``train/pen_skill_bc.py`` (runs)    ``pen_skill_bc.md``
``completion_table.json``              ``train/completion_table.py``       ``completion.md``
``offline_rl_results.json``            ``train/offline_rl.py`` (runs),      ``offline_rl.md``
                                       ``train/offline_table.py``
``robustness_{penslide,penrotate}_     ``ias-gym robustness --json`` kept   ``robustness_pen.md``
{expert,bc,random}.json``              by ``train/keep_run.py``
``evaluation_{penslide,penrotate}_     ``ias-gym evaluate --json``, the     ``evaluation_pen.md``
{expert,random}.json``                 same
``learning_{penslide,penrotate}_       the same                            ``learning.md``
{bc,bc_ppo,ppo}.json``
``robustness_shadow.json``             the same                            ``robustness_shadow.md``
``robustness_leap.json``               the same                            ``robustness_leap.md``
``dagger_results.json``                ``train/dagger.py`` (runs)          ``dagger.md``
``dagger_results.json``                ``train/dagger.py`` (seed_runs)     ``dagger_seeds.md``
``dagger_results.json``                ``train/dagger.py --ensemble 3``    ``dagger_ensembles.md``
                                       (ensemble_runs)
``dagger_results.json``                ``train/dagger.py --families ...``  ``dagger_push_``
                                       (push_weighted_runs)                ``weighted.md``
``dagger_results.json``                ``train/dagger.py --takeover G``    ``dagger_gate.md``
                                       (gate_runs)
``dagger_results.json``                the same, ``--families ...,``       ``dagger_``
                                       ``combined`` (combined_runs)        ``combined.md``
``sac_demos_results.json``             ``train/sac_demos.py`` (runs)       ``sac_demos.md``
``benchmarks/NAME.json``               ``bench/NAME.py --json``            ``NAME.md``
                                       (``make bench``: all of them)
=====================================  ==================================  =================

    python docs/_scripts/result_tables.py   # print every table
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

Table = Callable[[Mapping[str, Any]], str]


def percent(value: float | None) -> str:
    """``0.845`` as ``84 %``; ``-`` for a missing value."""
    return "-" if value is None else f"{100 * value:.0f} %"


def interval(rate: Mapping[str, Any] | None) -> str:
    """A rate of the JSON (:meth:`ias_gym.rates.Rate.to_dict`) as ``84 % [75, 90] (42/50)``:
    its counts, checked and printed by :class:`ias_gym.rates.Rate`; ``-`` for none (no
    session judged)."""
    from ias_gym.rates import Rate

    if rate is None:
        return "-"
    return str(Rate(int(rate["successes"]), int(rate["trials"])))


def number(value: float | None, digits: int) -> str:
    """A float with ``digits`` decimals; ``-`` for a missing value."""
    return "-" if value is None else f"{value:.{digits}f}"


def rows(header: Sequence[str], body: Sequence[Sequence[str]]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in body]
    return "\n".join(lines) + "\n"


def _with_interval(rate: float, trials: int) -> str:
    """``rate`` of ``trials`` as ``84 % [75, 90]`` (95 % Wilson interval)."""
    from ias_gym.rates import wilson_interval

    low, high = wilson_interval(round(rate * trials), trials)
    return f"{percent(rate)} [{100 * low:.0f}, {100 * high:.0f}]"


def transfer(result: Mapping[str, Any]) -> str:
    """Per hand, method and disturbance, over all skills (the JSON has each skill class)."""
    names = {"gt": "G(t)", "gt:ki=4000": "G(t) + integral"}
    body = []
    for key, s in result["summary"].items():
        hand, method, disturbance, group = key.split("|")
        if group != "all":
            continue
        margin = s["margin_err_rel"]
        body.append(
            [
                hand,
                names.get(method, method),
                disturbance,
                str(s["runs"]),
                _with_interval(s["success_rate"], s["runs"]),
                str(s.get("refused", 0)),
                f"{s['held']} / {s['tracked']} / {s['margin_kept']}",
                f"{number(s['rot_rms_deg'], 2)} / {number(s['rot_rms_deg_max'], 2)}",
                number(s["pos_rms_mm"], 2),
                percent(margin) if margin is None else f"{100 * margin:.1f} %",
            ]
        )
    header = [
        "hand",
        "method",
        "disturbance",
        "runs",
        "success [95 % interval]",
        "refused",
        "held / tracked / margin kept",
        "rotation RMS [deg] mean / worst",
        "position RMS [mm]",
        "margin error",
    ]
    intro = (
        f"{len(result['runs'])} runs: the glove sessions of {len(result['persons'])} simulated "
        f"persons on the hands {', '.join(result['hands'])} by the methods "
        f"{', '.join(result['methods'])} under {', '.join(result['disturbances'])}; "
        "`weak_*` are the executions the test must fail (nominal only).\n\n"
    )
    return intro + rows(header, body)


HAND_NAMES = {"ias4f": "ias4f", "ias3f": "ias3f", "shadow": "Shadow", "leap": "LEAP"}
"""The hands in the order and spelling of the docs' tables."""


def hand_reach(result: Mapping[str, Any]) -> str:
    """Per hand: its tilt and rate, then per tilt share the reach each way along each axis
    and the least of each plane's four diagonals [mm]."""
    directions = list(result["directions"])
    body = []
    for hand, name in HAND_NAMES.items():
        envelope = result["hands"][hand]
        tilt = math.degrees(envelope["tilt_rad"])
        for share in result["tilt_shares"]:
            reach = envelope["reach"][str(share)]
            axes = [f"{reach[f'+{a}_mm']:.0f} / {reach[f'-{a}_mm']:.0f}" for a in "xyz"]
            planes = [
                min(reach[f"{d}_mm"] for d in directions if len(d) == 4 and d[1::2] == plane)
                for plane in ("xy", "yz", "xz")
            ]
            first = share == result["tilt_shares"][0]
            body.append(
                [
                    name if first else "",
                    f"{tilt:.1f}" if first else "",
                    f"{math.degrees(envelope['tilt_rate_rad_s']):.0f}" if first else "",
                    f"{share * tilt:.1f}",
                    *axes,
                    *(f"{mm:.0f}" for mm in planes),
                ]
            )
    header = [
        "hand",
        "tilt [deg]",
        "rate [deg/s]",
        "at tilt [deg]",
        "x + / - [mm]",
        "y + / -",
        "z + / -",
        "xy diagonals, least",
        "yz",
        "xz",
    ]
    return rows(header, body)


def transfer_skills(result: Mapping[str, Any]) -> str:
    """Success per skill class (rows) and hand (columns) of each method, disturbance nominal."""
    summary = result["summary"]
    hands, methods = result["hands"], result["methods"]
    skills = sorted(
        {k.split("|")[3] for k in summary} - {"all", "held-out", "development"},
    )
    header = ["method", "skill", *hands]
    body = []
    for method in methods:
        for skill in skills:
            cells = []
            for hand in hands:
                s = summary.get(f"{hand}|{method}|nominal|{skill}")
                if s is None:
                    cells.append("-")
                    continue
                refused = f", {s['refused']} refused" if s.get("refused") else ""
                cells.append(f"{percent(s['success_rate'])} ({s['runs']}{refused})")
            body.append([method, skill, *cells])
    intro = "Success (runs, of them refused by the hand) per skill class, nominal.\n\n"
    return intro + rows(header, body)


#: The recognition rates with intervals (``methods.<m>.rates`` of the JSON) -> column titles.
RECOGNITION_RATES = {
    "recog_acc_at_60": "correct at 60 % of the motion",
    "final_accuracy": "correct at the end",
    "false_trigger_rate": "false triggers",
    "switches_followed": "intent switches followed",
}


def recognition(result: Mapping[str, Any]) -> str:
    """Each recogniser's scores, its accuracy by observed fraction, and on-line acquisition."""
    methods = result["methods"]
    names = {
        "dtw": "DTW (baseline)",
        "phase": "phase model",
        "phase_single": "phase model, no switches",
    }
    keys = [
        k
        for k, v in next(iter(methods.values())).items()
        if k not in ("method", "sessions", "switches") and not isinstance(v, dict)
    ]
    scores = rows(
        ["method", *keys],
        [[names.get(n, n), *(number(m.get(k), 3) for k in keys)] for n, m in methods.items()],
    )
    fractions = list(next(iter(methods.values()))["accuracy_by_fraction"])
    by_fraction = rows(
        ["method", *(f"{100 * float(f):.0f} %" for f in fractions)],
        [
            [names.get(n, n), *(number(m["accuracy_by_fraction"][f], 2) for f in fractions)]
            for n, m in methods.items()
        ],
    )
    acquisition = result.get("acquisition", {})
    demos = len(next(iter(acquisition.values()))["new_skill_accuracy"]) if acquisition else 0
    acquired = rows(
        ["method", "skill", *(f"n={n}" for n in range(1, demos + 1))],
        [
            [names.get(n, n), which, *(number(v, 2) for v in a[f"{which}_skill_accuracy"])]
            for n, a in acquisition.items()
            for which in ("new", "known")
        ],
    )
    intervals = rows(
        ["method", *RECOGNITION_RATES.values()],
        [
            [names.get(n, n), *(interval(m["rates"].get(k)) for k in RECOGNITION_RATES)]
            for n, m in methods.items()
            if "rates" in m
        ],
    )
    return (
        f"Library: {result['library_sessions']} sessions of {result['library_persons']} "
        f"development persons (population seed {result['library_seed']}); evaluated on "
        f"{result['held_out_sessions']} sessions of {result['persons']} persons drawn with "
        f"population seed {result['population_seed']} (**{result['set']}**).\n\n"
        + scores
        + "\nThe proportions over sessions with their 95 % Wilson intervals:\n\n"
        + intervals
        + "\nAccuracy by observed fraction of the skill's motion:\n\n"
        + by_fraction
        + "\nOn-line acquisition: accuracy on the held-out sessions after n demonstrations of "
        "the skill left out (mean over the skills), and on the known skills meanwhile:\n\n"
        + acquired
    )


#: How a table names the simulated person it was measured with (the JSON's ``operator``).
OPERATOR_NAMES = {
    "closed_loop": 'the person in the loop (`operator="closed_loop"`)',
    "script": 'the open-loop script (`operator="script"`)',
}


#: The assistant's parts an ablation arm of ``train/assist_population.py`` switches off.
PART_NAMES = {
    "pads": "the pad keeping",
    "tremor": "the tremor canceller",
    "completion": "the completion",
    "detection": "the tremor's detection",
}


def _size(value: float | None) -> str:
    """An intervention size, or a dash where an arm judged no session."""
    return "-" if value is None else f"{value:.2f}"


#: The observation assistant's held-out draws on population persons, in the order they were
#: run, each with what the assistant had gained before it (its JSON in ``docs/``; every
#: draw was run once, on a population seed drawn after that change).
ASSIST_DRAWS = (
    (
        "assist_unimpaired_population.json",
        "a pad alone counted from the library's first touch; the fit's start on either side "
        "of the onset",
    ),
    ("assist_redraw_population.json", "the same assistant, another draw"),
    ("assist_detection_population.json", "the tremor's detection (`tremor_floor_rad`)"),
    ("assist_switch_population.json", "the switching phase recogniser, its temper fitted"),
    ("assist_pace_population.json", "`catch_up_pace` fitted"),
    ("assist_reset_population.json", "the stop test reset as it is latched"),
    (
        "assist_hold_population.json",
        "`stop_hold_s`, `min_remaining_rad` and `min_model_speed` fitted",
    ),
)


def assist_draws(draws: Sequence[tuple[str, Mapping[str, Any]]]) -> str:
    """One row per held-out draw of the observation assistant (:data:`ASSIST_DRAWS`): the
    change before it, its persons and population seed, and the assisted success [95 %
    interval] of an unimpaired operator, of sampled families (beside alone) and of a
    stopped skill."""
    body = []
    for change, result in draws:
        by = result["by_impairment"]

        def cell(spec: str, arm: str, by: Mapping[str, Any] = by) -> str:
            return interval(by[spec][arm]) if spec in by else "-"

        body.append(
            [
                change,
                f"{result['persons']} of seed {result['population_seed']}",
                cell("none", "assisted"),
                cell("sampled", "unassisted"),
                cell("sampled", "assisted"),
                cell("stops:at=0.4", "assisted"),
            ]
        )
    header = [
        "the assistant, after",
        "persons",
        "unimpaired, assisted",
        "`sampled`, alone",
        "`sampled`, assisted",
        "`stops:at=0.4`, assisted",
    ]
    intro = (
        "Each draw: population persons, the person in the loop, the skills with a motion of "
        "their own, success [95 % interval] (successes/sessions judged).\n\n"
    )
    return intro + rows(header, body)


def assist_population(result: Mapping[str, Any]) -> str:
    """The observation assistant on population persons: success [95 % interval] per
    impairment spec, unassisted, assisted and without skill knowledge (and with a learned
    residual on top, where the run has one)."""
    arms = {
        "unassisted": "unassisted",
        "assisted": "assisted (phase recogniser)",
        "no_skill_knowledge": "no skill knowledge",
    }
    if result.get("residual"):
        arms["residual"] = "assisted + learned residual"
    for part in result.get("without", []):
        arms[f"without_{part}"] = f"assisted without {PART_NAMES.get(part, part)}"
    body = [
        [f"`{spec}`", *(interval(row[arm]) for arm in arms), str(row["excluded"])]
        for spec, row in result["by_impairment"].items()
    ]
    library = result.get("library", "shipped")
    intro = (
        f"{result['persons']} persons of population seed {result['population_seed']} "
        f"(**{result['set']}**), the skills with a motion of their own "
        f"({', '.join(result['skills'])}), reset seed 0, library `{library}`, "
        f"{OPERATOR_NAMES[result['operator']]}; success [95 % "
        "interval] (successes/sessions judged), and the sessions left out for want of a "
        "reference.\n\n"
    )
    table = intro + rows(["impairment", *arms.values(), "left out"], body)
    helped = [arm for arm in arms if arm != "unassisted"]
    sized = {
        s: row["intervention"]
        for s, row in result["by_impairment"].items()
        if "intervention" in row
    }
    if sized:
        size_rows = [
            [f"`{spec}`", *(_size(per_arm.get(arm)) for arm in helped)]
            for spec, per_arm in sized.items()
        ]
        table += (
            "\nIntervention (the mean over the judged sessions of the size of the assistant's "
            "offsets over the operator's own motion):\n\n"
            + rows(["impairment", *(arms[a] for a in helped)], size_rows)
        )
    specs = [s for s, row in result["by_impairment"].items() if "assisted_by_skill" in row]
    if specs:
        skill_rows = [
            [
                f"`{skill}`",
                *(interval(result["by_impairment"][s]["assisted_by_skill"][skill]) for s in specs),
            ]
            for skill in result["skills"]
        ]
        table += "\nAssisted (phase recogniser), by skill:\n\n" + rows(
            ["skill", *(f"`{s}`" for s in specs)], skill_rows
        )
    for spec, row in result["by_impairment"].items():
        if "by_family" in row:
            family_rows = [
                [f"`{family}`", *(interval(per_arm[arm]) for arm in arms)]
                for family, per_arm in row["by_family"].items()
            ]
            table += f"\n`{spec}`, by the family each session drew:\n\n" + rows(
                ["family", *arms.values()], family_rows
            )
    return table


def assist_acquisition(result: Mapping[str, Any]) -> str:
    """The loop closed: a skill left out of the library, acquired from demonstrations, and
    completed for stopped operators after each; beside the operator alone and the whole
    library."""
    entries = {**{f"`{k}`": v for k, v in result["by_skill"].items()}, "all": result["all"]}
    n = len(result["all"]["stopped_after"])
    body = [
        [
            name,
            interval(e["stopped_alone"]),
            interval(e["stopped_shipped"]),
            *(interval(r) for r in e["stopped_after"]),
            interval(e["recognised_after"][-1]),
            interval(e["unimpaired_after"][-1]),
        ]
        for name, e in entries.items()
    ]
    header = [
        "skill",
        "alone",
        "whole library",
        *(f"after {k + 1}" for k in range(n)),
        f"recognised after {n}",
        f"unimpaired after {n}",
    ]
    stored = {
        k: sum(d.get("stored") is not None for d in e["demonstrations"])
        for k, e in result["by_skill"].items()
    }
    intro = (
        f"`{result['impairment']}`, {result['persons']} persons of population seed "
        f"{result['population_seed']} (**{result['set']}**); demonstrators: population seed "
        f"{result['demonstrator_seed']}, library `{result['library']}` less the skill; "
        "success [95 % interval] (successes/sessions judged) of the stopped operator alone, "
        "assisted with the whole library, and assisted after each demonstration; the "
        "acquired skill as the recogniser's final answer on unimpaired sessions, and their "
        "success, after the last. Demonstrations stored: "
        + ", ".join(f"{k} {v}" for k, v in stored.items())
        + ".\n\n"
    )
    return intro + rows(header, body)


def assistance(phase: Mapping[str, Any], residual: Mapping[str, Any]) -> str:
    """The analytic assistant with the phase recogniser and the learned residual on it (on
    the true intent) on population persons: success [95 % interval] unassisted and assisted,
    the intervention in brackets, per impairment."""
    same = ("population", "seed", "operator")
    if [phase[k] for k in same] != [residual[k] for k in same]:
        raise ValueError("the two assistance tables are of different persons, seeds or operators")
    body = []
    for impairment, row in phase["analytic+phase"].items():
        other = residual["residual"][impairment]
        body.append(
            [
                impairment,
                interval(row["unassisted"]),
                f"{interval(row['assisted'])} ({number(row['intervention'], 3)})",
                f"{interval(other['assisted'])} ({number(other['intervention'], 3)})",
                str(row["excluded"]),
            ]
        )
    header = [
        "impairment",
        "unassisted",
        "analytic + phase recogniser",
        "residual PPO + true intent",
        "left out",
    ]
    table = rows(header, body)
    latency = phase.get("switch_latency", {}).get("analytic+phase")
    note = ""
    if latency:
        note = (
            f"\nIntent switches ({latency['n']}): the phase recogniser settles on the new skill "
            f"in {latency['n'] - latency['never']}, after a median "
            f"{number(latency['median_s'], 2)} s (max {number(latency['max_s'], 2)} s).\n"
        )
    n, seed = phase["population"]
    intro = (
        f"{n} persons of population seed {seed} (**{phase['set']}**) x "
        f"{len(phase['skills'])} skills, each impairment once per person and skill (reset "
        f"seeds {phase['seed']}-{phase['seed'] + len(phase['skills']) - 1}), "
        f"{OPERATOR_NAMES[phase['operator']]}; success [95 % "
        "interval] (successes/sessions judged), the intervention in brackets, and the "
        "sessions left out for want of a reference.\n\n"
    )
    return intro + table + note


#: The groups of ``train/pen_skill_bc.py``'s split, as the table names them.
GROUPS = {
    "train": "training skills x persons (new seed)",
    "heldout_skill": "held-out skills, training persons",
    "heldout_person": "training skills, held-out persons",
    "heldout_both": "held-out skills, held-out persons",
}


def pen_skill_bc(result: Mapping[str, Any]) -> str:
    """Success [95 % interval] of the expert, the learned policy (BC or DAgger, as the run's
    name says) and its PPO fine-tuning per training run and group, with the learned
    policy's errors (random policies: 0 % in every group, in the JSON)."""
    body = []
    for run in result["runs"]:
        res = run["results"]
        n_persons, seed = res["heldout_population"]
        for group, per_policy in res["groups"].items():
            bc = per_policy["bc"]
            open_loop = res.get("open_loop", {}).get(group, {})
            body.append(
                [
                    f"{run['name']}; held-out: {n_persons} of seed {seed} ({res['set']})",
                    GROUPS.get(group, group),
                    *(interval(per_policy[p]["success"]) for p in ("expert", "bc", "bc_ppo")),
                    f"{number(bc.get('rms_position_error_mean_mm'), 2)} / "
                    f"{number(bc.get('rms_rotation_error_mean_deg'), 2)}",
                    number(open_loop.get("bc_action_rms_error"), 4),
                    number(open_loop.get("max_abs_z"), 0),
                ]
            )
    header = [
        "run",
        "group",
        "expert",
        "learned (BC or DAgger)",
        "learned + PPO",
        "learned: RMS pos. / axis err. [mm / deg]",
        "learned: open-loop action err.",
        "max abs z",
    ]
    return rows(header, body)


def pen_skill_bc_robustness(result: Mapping[str, Any]) -> str:
    """The robustness suite on the held-out persons' training skills: success [95 % interval]
    of the expert and of each run's cloned policy per class (runs without it left out)."""
    runs = [run for run in result["runs"] if run["results"].get("robustness")]
    if not runs:
        return "No run measured the robustness suite.\n"
    columns: list[tuple[str, Any]] = []
    experts = set()  # one expert column per hand and set of persons
    for run in runs:
        res = run["results"]
        key = (res["hand"], tuple(res["heldout_population"]))
        if key not in experts:
            experts.add(key)
            columns.append((f"expert ({res['hand']})", res["robustness"]["expert"]))
        columns.append((f"learned: {run['name']}", res["robustness"]["bc"]))
    body = [
        [row["disturbance"], *(interval(rows_[k]) for _, rows_ in columns)]
        for k, row in enumerate(columns[0][1])
    ]
    return rows(["class", *(name for name, _ in columns)], body)


def completion(result: Mapping[str, Any]) -> str:
    """Success with its 95 % Wilson interval per operator and skill."""
    tables = result["tables"]
    skills = list(next(iter(tables.values())))
    body = []
    for skill in skills:
        row = [skill]
        for per_skill in tables.values():
            row.append(interval(per_skill[skill]))
        body.append(row)
    header = ["skill", *(f"{name} operator" for name in tables)]
    intro = (
        f"{result['persons']} {result['set']} persons of population seed "
        f"{result['population_seed']}, every skill once; success [95 % interval].\n\n"
    )
    return intro + rows(header, body)


#: The columns of the offline-RL table: (algorithm key of the JSON, heading).
OFFLINE_COLUMNS = (
    ("bc", "BC"),
    ("iql", "IQL"),
    ("cql", "CQL"),
    ("awac", "AWAC"),
    ("sb3_bc", "BC (ias-gym)"),
)


def offline_rl(result: Mapping[str, Any]) -> str:
    """CORL's layout: a row per dataset, a column per method, the normalised score (random
    0, expert 100) as mean +- std over training seeds, the success rate below; the
    published D4RL pen-human scores as a reference row."""
    cells = {(c["dataset_id"], c["algorithm"]): c for c in result["cells"]}
    datasets = list(dict.fromkeys(c["dataset_id"] for c in result["cells"]))
    header = ["dataset", *(name for _, name in OFFLINE_COLUMNS)]

    def cell(dataset: str, algo: str, key: str, scale: float, digits: int) -> str:
        c = cells.get((dataset, algo))
        if c is None:
            return "-"
        mean, std = scale * c[f"{key}_mean"], scale * c[f"{key}_std"]
        return f"{mean:.{digits}f} ± {std:.{digits}f}"

    scores = [
        [f"`{d}`", *(cell(d, a, "normalised_score", 1.0, 1) for a, _ in OFFLINE_COLUMNS)]
        for d in datasets
    ]
    ref = result["reference"]
    scores.append(
        [
            f"{ref['dataset']} (D4RL Adroit, published: reference)",
            *(
                "-"
                if a not in ref["normalised_score"]
                else "{:.1f} ± {:.1f}".format(*ref["normalised_score"][a])
                for a, _ in OFFLINE_COLUMNS
            ),
        ]
    )
    success = [
        [f"`{d}`", *(cell(d, a, "success_rate", 100.0, 0) for a, _ in OFFLINE_COLUMNS)]
        for d in datasets
    ]
    runs = "".join(
        f"- `{c['dataset_id']}`, {c['algorithm']}: {c['steps']} {c['steps_unit']}, seeds "
        f"{', '.join(str(r['seed']) for r in c['runs'])}, {c['eval_episodes']} {c['set']} "
        f"episodes (seeds {c['eval_seeds'][0]}-{c['eval_seeds'][1]}), "
        f"{max(r['train_seconds'] for r in c['runs']) / 60:.1f} min a run at most: "
        f"`{c['command']}`\n"
        for c in result["cells"]
    )
    return (
        "Normalised score (random 0, expert 100), mean ± std over training seeds:\n\n"
        + rows(header, scores)
        + "\nSuccess rate [%], mean ± std over the same runs:\n\n"
        + rows(header, success)
        + "\n"
        + runs
        + f"\nReference: {ref['source']}.\n"
    )


def robustness(results: Sequence[Mapping[str, Any]]) -> str:
    """Success with its 95 % Wilson interval per disturbance class, one column per run of
    ``ias-gym robustness --json`` (kept by ``train/keep_run.py`` with the command and
    the seed set)."""

    per_run = [
        {r["disturbance"]: r for r in result["rows"] if r["disturbance"] != "all"}
        for result in results
    ]
    classes = list(per_run[0])
    body = [
        [f"`{name}`", *(interval(run[name]) if name in run else "-" for run in per_run)]
        for name in classes
    ]
    body.append(
        ["**minimum**", *(percent(min(r["success_rate"] for r in run.values())) for run in per_run)]
    )
    header = ["disturbance", *(f"{r['policy']} `{r['env']}`" for r in results)]
    intro = "".join(
        f"- `{r['policy']}` on `{r['env']}`: {r['set']} seeds {r['seed']}-"
        f"{r['seed'] + r['episodes'] - 1}, {r['episodes']} episodes per class: "
        f"`{r['command']}`\n"
        for r in results
    )
    return intro + "\nSuccess [95 % interval] (successes/episodes).\n\n" + rows(header, body)


def evaluation(results: Sequence[Mapping[str, Any]]) -> str:
    """One row per run of ``ias-gym evaluate --json`` (kept by ``train/keep_run.py``): success
    with its 95 % interval, mean return and length, and each task error's mean / max over
    the episodes, its unit from its key (``..._mean_mm``, ``..._max_mm``)."""
    body = []
    for result in results:
        r = result["rows"][0]
        errors = []
        for key in r:
            stem, _, unit = key.rpartition("_")
            if stem.endswith("_mean") and f"{stem[:-5]}_max_{unit}" in r:
                name = stem[:-5].replace("_", " ")
                worst = r[f"{stem[:-5]}_max_{unit}"]
                errors.append(f"{name} {number(r[key], 2)} / {number(worst, 2)} {unit}")
        body.append(
            [
                f"`{result['env']}`",
                result["policy"],
                f"{result['seed']}-{result['seed'] + result['episodes'] - 1}",
                _with_interval(r["success_rate"], r["episodes"]),
                number(r["mean_return"], 1),
                number(r["mean_length"], 0),
                "; ".join(errors),
            ]
        )
    header = [
        "env",
        "policy",
        "seeds",
        "success [95 %]",
        "mean return",
        "mean length [steps]",
        "task errors, mean / max over episodes",
    ]
    commands = "".join(f"- `{result['command']}`\n" for result in results)
    return commands + "\n" + rows(header, body)


def dagger(result: Mapping[str, Any]) -> str:
    """Each DAgger run beside its behaviour-cloning baseline, per disturbance class; one table
    per env."""
    learners = ("dagger", "bc")
    parts = []
    for env in dict.fromkeys(run["env"] for run in result["runs"]):
        runs = [run for run in result["runs"] if run["env"] == env]
        classes = list(runs[0]["evaluation"]["dagger"])
        body = []
        for name in classes:
            row = [f"`{name}`"]
            for run in runs:
                for learner in learners:
                    s = run["evaluation"][learner][name]
                    row.append(
                        f"{percent(s['success_rate'])} [{100 * s['ci95_low']:.0f}, "
                        f"{100 * s['ci95_high']:.0f}]"
                    )
            body.append(row)
        header = ["disturbance"]
        header += [
            f"{'DAgger' if lr == 'dagger' else 'BC'} ({run['run']})"
            for run in runs
            for lr in learners
        ]
        intro = "".join(
            f"- `{run['run']}`: {run['note']}; {run['expert_labels']} expert labels, "
            f"{run['evaluation_set']} seeds from {run['evaluation_first_seed']}, "
            f"{run['evaluation_episodes_per_class']} episodes per class: "
            f"`{result['reproduce'][run['run']]}`\n"
            for run in runs
        )
        parts.append(f"{env}; success [95 % interval].\n\n" + intro + "\n" + rows(header, body))
    return "\n\n".join(parts)


def seed_table(
    runs: Sequence[Mapping[str, Any]],
    learners: Sequence[tuple[str, str]],
    reproduce: Mapping[str, str],
) -> str:
    """Per env and disturbance class, each learner's success over training seeds: mean +-
    standard deviation (the seeds' own values in brackets).

    Args:
        runs: one result per (env, training seed), each with ``evaluation[learner][class]``.
        learners: ``(key in evaluation, column name)``.
        reproduce: the command of an env's runs.
    """
    import statistics

    parts = []
    for env in dict.fromkeys(run["env"] for run in runs):
        mine = sorted((r for r in runs if r["env"] == env), key=lambda r: r["train_seed"])
        first = mine[0]
        body = []
        for name in first["evaluation"][learners[0][0]]:
            row = [f"`{name}`"]
            for learner, _ in learners:
                values = [100 * r["evaluation"][learner][name]["success_rate"] for r in mine]
                each = ", ".join(f"{v:.0f}" for v in values)
                row.append(
                    f"{statistics.mean(values):.0f} +- {statistics.stdev(values):.0f} ({each})"
                )
            body.append(row)
        seeds = ", ".join(str(r["train_seed"]) for r in mine)
        parts.append(
            f"{env}: training seeds {seeds}; {first['evaluation_set']} seeds from "
            f"{first['evaluation_first_seed']}, {first['evaluation_episodes_per_class']} "
            "episodes per class; success [%], mean +- standard deviation over the training "
            f"seeds (each seed's): `{reproduce[env]}`\n\n"
            + rows(["disturbance", *(name for _, name in learners)], body)
        )
    return "\n\n".join(parts)


def dagger_seeds(result: Mapping[str, Any], key: str = "seed_runs") -> str:
    """DAgger's and BC's success over training seeds (:func:`seed_table`); ``key``: the runs'
    list in ``result`` (their command per env under ``reproduce_<key>``)."""
    runs = result[key]
    size = int(runs[0].get("ensemble", 1))
    names = ("DAgger", "BC") if size == 1 else (f"DAgger, {size} clones", f"BC, {size} clones")
    # Runs without the BC baseline (``--no-baseline``) have DAgger's column alone.
    learners = tuple(
        (learner, name)
        for learner, name in zip(("dagger", "bc"), names, strict=True)
        if learner in runs[0]["evaluation"]
    )
    return seed_table(runs, learners, result[f"reproduce_{key}"])


def sac_demos(result: Mapping[str, Any]) -> str:
    """SAC with demonstrations over training seeds: its pretrained actor and after RL
    (:func:`seed_table`), and what the runs spent."""
    runs = result["runs"]
    table = seed_table(
        runs,
        (("pretrained", "actor pretrained by cloning"), ("sac_demos", "after SAC")),
        result["reproduce"],
    )
    spent = [
        [
            r["env"],
            str(r["train_seed"]),
            str(r["demo_transitions"]),
            str(r["env_steps"]),
            f"{sum(r['wall_time_s'].values()) / 60:.1f}",
        ]
        for r in runs
    ]
    header = ["env", "seed", "demonstration steps", "RL env steps", "wall-clock [min]"]
    return (
        table
        + "\n\nWhat each run spent (demonstrations, pretraining and RL):\n\n"
        + rows(header, spent)
    )


def benchmark(result: Mapping[str, Any]) -> str:
    """One run of a ``bench/`` script (``bench/report.py``): its tables, goals and machine."""
    if result.get("schema") != "ias-gym/bench-v1":
        raise ValueError(f"{result.get('script')}: not a benchmark result (ias-gym/bench-v1)")
    m = result["machine"]
    parts = [
        f"`{result['command']}`, {result['date_utc']} UTC; {m['cpu']}, {m['cores']} cores, "
        f"load {m['load_average_1min']}, Python {m['python']}, MuJoCo {m['mujoco']}, numpy "
        f"{m['numpy']}.\n"
    ]
    for table in result["tables"]:
        if any(len(r) != len(table["header"]) for r in table["rows"]):
            raise ValueError(f"{result['script']}: {table['title']!r} has rows of another width")
        parts.append(f"\n{table['title']}:\n\n" + rows(table["header"], table["rows"]))
    if result["notes"]:
        parts.append("\n" + "".join(f"- {text}\n" for text in result["notes"]))
    if result["checks"]:
        parts.append("\nGoals in this run:\n\n")
        parts += [
            f"- {'met' if c['met'] else '**not met**'}: {c['goal']}"
            + (f" ({c['measured']})" if c["measured"] else "")
            + "\n"
            for c in result["checks"]
        ]
    return "".join(parts)


BENCHMARKS = (
    "bench_internal_forces",
    "bench_envs",
    "bench_vector",
    "bench_controller",
    "bench_glove",
    "bench_glove_loop",
    "bench_glove_speed",
    "bench_shadow_adroit",
)
"""The benchmarks whose latest runs (``docs/benchmarks/NAME.json``) the page shows."""

PEN_EVALUATION = tuple(
    f"evaluation_{task}_{policy}.json"
    for task in ("penslide", "penrotate")
    for policy in ("expert", "random")
)
"""The pen tasks' runs of ``ias-gym evaluate``, one row each."""

PEN_LEARNING = tuple(
    f"learning_{task}_{method}.json"
    for task in ("penslide", "penrotate")
    for method in ("bc", "bc_ppo", "ppo")
)
"""The learned policies' runs of ``ias-gym evaluate``, one row each."""

PEN_ROBUSTNESS = tuple(
    f"robustness_{task}_{policy}.json"
    for policy in ("expert", "shipped", "bc", "random")
    for task in ("penslide", "penrotate")
)
"""The pen tasks' runs of ``ias-gym robustness``, one column each."""


def tables(docs: Path) -> dict[str, str]:
    """Every table by its file name, from the JSON files in ``docs``."""

    def load(name: str) -> Mapping[str, Any]:
        loaded: Mapping[str, Any] = json.loads((docs / name).read_text())
        return loaded

    return {
        "transfer.md": transfer(load("transfer_results.json")),
        "transfer_skills.md": transfer_skills(load("transfer_results.json")),
        "hand_reach.md": hand_reach(load("hand_reach.json")),
        "recognition.md": recognition(load("recognition_results.json")),
        "assistance.md": assistance(
            load("assist_table_phase.json"), load("assist_table_residual.json")
        ),
        "assist_population.md": assist_population(load("assist_population.json")),
        "assist_residual_population.md": assist_population(load("assist_residual_population.json")),
        "assist_pads_population.md": assist_population(load("assist_pads_population.json")),
        "assist_trend_population.md": assist_population(load("assist_trend_population.json")),
        "assist_draws.md": assist_draws([(c, load(name)) for name, c in ASSIST_DRAWS]),
        "assist_latest_draw.md": assist_population(load(ASSIST_DRAWS[-1][0])),
        "assist_acquisition.md": assist_acquisition(load("assist_acquisition.json")),
        "pen_skill_bc.md": pen_skill_bc(load("pen_skill_bc_results.json")),
        "pen_skill_bc_robustness.md": pen_skill_bc_robustness(load("pen_skill_bc_results.json")),
        "completion.md": completion(load("completion_table.json")),
        "offline_rl.md": offline_rl(load("offline_rl_results.json")),
        "evaluation_pen.md": evaluation([load(name) for name in PEN_EVALUATION]),
        "learning.md": evaluation([load(name) for name in PEN_LEARNING]),
        "robustness_pen.md": robustness([load(name) for name in PEN_ROBUSTNESS]),
        "robustness_shadow.md": robustness([load("robustness_shadow.json")]),
        "robustness_leap.md": robustness([load("robustness_leap.json")]),
        "dagger.md": dagger(load("dagger_results.json")),
        "dagger_seeds.md": dagger_seeds(load("dagger_results.json")),
        "dagger_ensembles.md": dagger_seeds(load("dagger_results.json"), "ensemble_runs"),
        "dagger_push_weighted.md": dagger_seeds(load("dagger_results.json"), "push_weighted_runs"),
        "dagger_gate.md": dagger_seeds(load("dagger_results.json"), "gate_runs"),
        "dagger_combined.md": dagger_seeds(load("dagger_results.json"), "combined_runs"),
        "sac_demos.md": sac_demos(load("sac_demos_results.json")),
        **{f"{name}.md": benchmark(load(f"benchmarks/{name}.json")) for name in BENCHMARKS},
    }


def write_tables(docs: Path, out: Path) -> None:
    """Write every table into ``out`` (unchanged files are left alone)."""
    out.mkdir(parents=True, exist_ok=True)
    for name, text in tables(docs).items():
        path = out / name
        if not path.exists() or path.read_text() != text:
            path.write_text(text)


if __name__ == "__main__":
    for table_name, table in tables(Path(__file__).resolve().parents[1]).items():
        print(f"## {table_name}\n\n{table}")

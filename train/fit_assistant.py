"""Fit the observation assistant's stop threshold on development persons, cross-validated.

For persons drawn from the population with ``--seed`` (development persons: never the
seed an evaluation reports), every skill with a motion is run twice with the assistant
watching but never acting (``stop_ratio`` 0: no stop is ever latched): once unimpaired and
once with ``stops:at=F`` (F drawn from the family's sample range per session). Each session
gives the smallest ratio of the operator's speed to the fitted model's at which a stop could
have been latched (:attr:`~ias_gym.assist.policy.ObservationAssistant.min_ratios`, the true
skill's). A threshold between the two classes is chosen to maximise balanced accuracy on
the training folds (folds are groups of persons, ``--folds``), and its false-trigger and
detection rates on the held-out folds are reported with 95 % intervals. The threshold fitted
on all persons is written to ``ias_gym/assets/assistant_params.json`` (``--out``; an existing
file only with ``--overwrite``).

    python train/fit_assistant.py --persons 30 --seed 7001 --overwrite
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from typing import Any

import gymnasium as gym
import numpy as np
from tqdm import tqdm

import ias_gym  # noqa: F401  (registers the envs)
from ias_gym.assist.policy import PARAMS_PATH, AssistParams, make_assistant
from ias_gym.assist.sessions import run_session
from ias_gym.assist.skill_motions import load_motions
from ias_gym.glove.impairment_spec import FAMILIES
from ias_gym.glove.impairments import session_rng
from ias_gym.glove.population import population_ids
from ias_gym.rates import Rate


def session_ratio(person: str, skill: str, spec: str, params: AssistParams, seed: int) -> float:
    """The smallest armed speed ratio of one watched session (inf if never armed)."""
    env = gym.make("IAS-GloveAssist-v0", person_id=person, skill=skill, impairment=spec)
    u: Any = env.unwrapped
    watch = dataclasses.replace(params, stop_ratio=1e-12)
    assistant = make_assistant(
        recogniser="none",
        params=watch,
        layout=u.observation_layout,
        control_dt=u.config.control_dt,
        action_scale=u.config.action_scale,
    )
    run_session(env, assistant, seed)
    env.close()
    return assistant.min_ratios[skill]


def best_threshold(unimpaired: np.ndarray, stopped: np.ndarray) -> float:
    """The threshold (midway between neighbouring observed values) with the best balanced
    accuracy: unimpaired ratios above it, stopped ones below."""
    values = np.unique(np.concatenate([unimpaired, stopped]))
    values = values[np.isfinite(values)]
    if not len(values):
        raise SystemExit("no session ever armed the stop test: nothing to fit on")
    cuts = (values[:-1] + values[1:]) / 2 if len(values) > 1 else values
    best, cut = -1.0, float(cuts[0])
    for c in cuts:
        score = np.mean(unimpaired >= c) + np.mean(stopped < c)
        if score > best:
            best, cut = float(score), float(c)
    return cut


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--persons", type=int, default=30, help="development persons")
    ap.add_argument("--seed", type=int, default=7001, help="population seed (development)")
    ap.add_argument("--folds", type=int, default=5, help="cross-validation groups of persons")
    ap.add_argument("--out", default=str(PARAMS_PATH), help="parameter file written")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    args = ap.parse_args(argv)
    persons = population_ids(args.persons, args.seed)
    skills = sorted(load_motions())
    base = AssistParams()
    rows = []
    with tqdm(total=2 * len(persons) * len(skills), desc="watched sessions") as bar:
        for k, person in enumerate(persons):
            for skill in skills:
                lo, hi = (float(v) for v in FAMILIES["stops"]["at"].sample)
                at = float(session_rng("fit-stops", person, skill).uniform(lo, hi))
                for spec, label in (("none", 0), (f"stops:at={at:.3f}", 1)):
                    ratio = session_ratio(person, skill, spec, base, 0)
                    rows.append((k % args.folds, label, ratio))
                    bar.update()
    data = np.array(rows)
    false_hits = detected = n_u = n_s = 0
    for fold in range(args.folds):
        train, test = data[data[:, 0] != fold], data[data[:, 0] == fold]
        cut = best_threshold(train[train[:, 1] == 0, 2], train[train[:, 1] == 1, 2])
        u, s = test[test[:, 1] == 0, 2], test[test[:, 1] == 1, 2]
        false_hits += int(np.sum(u < cut))
        detected += int(np.sum(s < cut))
        n_u, n_s = n_u + len(u), n_s + len(s)
    cut = best_threshold(data[data[:, 1] == 0, 2], data[data[:, 1] == 1, 2])
    fitted = dataclasses.replace(
        base,
        stop_ratio=round(cut, 4),
        fitted_on=f"{args.persons} population persons, seed {args.seed}, {len(skills)} skills",
    )
    try:
        fitted.save(args.out, overwrite=args.overwrite)
    except FileExistsError as e:
        print(f"{e} (give --overwrite)", file=sys.stderr)
        return 2
    report = {
        "stop_ratio": fitted.stop_ratio,
        "cv_false_triggers": Rate(false_hits, n_u).to_dict(),
        "cv_detections": Rate(detected, n_s).to_dict(),
        "persons": args.persons,
        "seed": args.seed,
    }
    print(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

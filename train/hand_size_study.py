"""The ``hand_size`` impairment judged against two references: which one measures the plan?

``hand_size`` runs the stock pinch (planned for a nominal hand) on the person's hand
resized to ``--scales``. Its session can be judged against

- ``own_hand``: the person's own hand with their own plan (how the impairment was judged
  until session 7, as ``small_hand`` at scale 0.8): plan *and* hand differ, so the pen also
  moves on another lever between wrist and pen;
- ``same_hand``: the same resized hand running a plan made for it (the env's
  ``hand_scale``; ``reference_kwargs``, the reference now): only the plan differs.

Per session it writes success against each, the position and axis errors, the env's success
and whether the pen was held, unassisted and with the analytic assistant (oracle intent),
to ``OUT.json``, and prints the shares (docs/assistance.md, "Another hand's size").

    PYTHONPATH=$PWD python train/hand_size_study.py --db out/library.db --out out/hand_size
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from tqdm import tqdm

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.assist.assistance_evaluation import reference_session
from ias_gym.assist.assistants import AnalyticAssistant
from ias_gym.assist.sessions import run_session, session_record
from ias_gym.assist.skill_templates import load_templates
from ias_gym.glove.skills import SKILLS


def main(argv: list[str] | None = None) -> int:
    """Run the study (arguments: ``--help``)."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument(
        "--persons", default="hc-631e84,hc-d7d59f,hc-d8d328,hc-6c0251,hc-b3d0f7,hc-7088f4"
    )
    parser.add_argument("--scales", default="0.8,1.2", help="hand scales [-], comma-separated")
    parser.add_argument("--seed", type=int, default=0, help="skill i runs from seed + i")
    parser.add_argument("--db", default=None, help="skill library (default: shipped)")
    parser.add_argument("--out", default="out/hand_size", help="writes OUT.json")
    parser.add_argument("--overwrite", action="store_true")
    args = parser.parse_args(argv)
    out = Path(args.out).with_suffix(".json")
    if out.exists() and not args.overwrite:
        print(f"{out} exists (--overwrite)", file=sys.stderr)
        return 2
    out.parent.mkdir(parents=True, exist_ok=True)
    persons = args.persons.split(",")
    scales = [float(s) for s in args.scales.split(",")]
    templates = load_templates(args.db)
    rows = []
    with tqdm(total=len(persons) * len(SKILLS) * len(scales), desc="sessions") as bar:
        for person in persons:
            for i, skill in enumerate(SKILLS):
                seed = args.seed + i
                own = reference_session(person, skill, seed)
                for scale in scales:
                    same = reference_session(person, skill, seed, hand_scale=scale)
                    env = gym.make(
                        "IAS-GloveAssist-v0",
                        person_id=person,
                        skill=skill,
                        impairment="hand_size",
                        strength=scale,
                    )
                    row: dict[str, Any] = {"person": person, "skill": skill, "seed": seed}
                    row["scale"] = scale
                    for name, assistant in (("unassisted", None), ("analytic", 0)):
                        result = run_session(
                            env, AnalyticAssistant(templates) if assistant == 0 else None, seed
                        )
                        row[name] = {
                            ref_name: None if ref is None else session_record(result, ref)
                            for ref_name, ref in (("own_hand", own), ("same_hand", same))
                        }
                    env.close()
                    rows.append(row)
                    bar.update(1)
    out.write_text(json.dumps(rows, indent=1))
    for scale in scales:
        for ref in ("own_hand", "same_hand"):
            for name in ("unassisted", "analytic"):
                ok = [
                    r[name][ref]["success"]
                    for r in rows
                    if r["scale"] == scale and r[name][ref] is not None
                ]
                share = f"{100 * np.mean(ok):.0f} %" if ok else "-"
                print(f"scale {scale:g}, against the {ref} reference, {name}: {share} of {len(ok)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

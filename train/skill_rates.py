"""How fast the persons move the pen in their demonstrations, per skill class.

    python train/skill_rates.py --db pop.db [--out-json rates.json]

For each successful session of the database: the peak speed of the pen's centre [mm/s] and
the peak rate of turn of its axis [rad/s] over the transfer window (3 s from the skill's
start), unscaled, on the reference grid a transfer executes (``transfer_reference``: 10 ms,
Savitzky-Golay derivatives). Printed per skill class as the median person's peak and the
largest; compare them with a hand's ``skill_speed`` and ``skill_tilt_rate``
(``train/hand_reach.py``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections import defaultdict
from collections.abc import Sequence
from typing import Any

import numpy as np

#: The transfer window [s] (``train/transfer_table.py``'s default duration).
DURATION = 3.0


def peak_rates(skill: Any) -> tuple[float, float]:
    """The peak speed of the pen's centre [mm/s] and rate of turn of its axis [rad/s] of a
    skill's transfer window, unscaled."""
    from ias_gym.skills.transfer import transfer_reference
    from ias_gym.skills.workspace import HandWorkspace

    unscaled = HandWorkspace(reach=math.inf, tilt=math.inf)
    ref = transfer_reference(skill, workspace=unscaled, duration=DURATION)
    speed = 1000.0 * float(np.linalg.norm(ref.velocity, axis=1).max())
    return speed, float(np.linalg.norm(ref.omega, axis=1).max())


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--db", required=True, help="the skill database")
    parser.add_argument("--out-json", help="the rates per class (default: print only)")
    parser.add_argument("--overwrite", action="store_true", help="replace --out-json")
    args = parser.parse_args(argv)
    from ias_gym.outputs import atomic_output, check_output_file
    from ias_gym.skills.db import SkillDB

    if args.out_json:
        check_output_file(args.out_json, overwrite=args.overwrite)
    by_class: dict[str, list[tuple[float, float]]] = defaultdict(list)
    with SkillDB(args.db, readonly=True) as db:
        for summary in db.list_skills(success=True):
            skill = db.get(summary.id)
            by_class[skill.name].append(peak_rates(skill))
    result = {}
    for name, rows in sorted(by_class.items()):
        a = np.array(rows)
        result[name] = {
            "sessions": len(rows),
            "speed_mm_s_median": float(np.median(a[:, 0])),
            "speed_mm_s_max": float(a[:, 0].max()),
            "turn_rate_rad_s_median": float(np.median(a[:, 1])),
            "turn_rate_rad_s_max": float(a[:, 1].max()),
        }
        r = result[name]
        print(
            f"{name}: {len(rows)} sessions; peak speed {r['speed_mm_s_median']:.0f} mm/s "
            f"(median person; largest {r['speed_mm_s_max']:.0f}), peak turn rate "
            f"{r['turn_rate_rad_s_median']:.2f} rad/s (largest {r['turn_rate_rad_s_max']:.2f})"
        )
    if args.out_json:
        with atomic_output(args.out_json, overwrite=args.overwrite) as tmp:
            tmp.write_text(json.dumps({"db": str(args.db), "classes": result}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

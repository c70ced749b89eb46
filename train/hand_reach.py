"""Measure how far each hand's expert carries the held pen along each axis, tilting it.

    python train/hand_reach.py --out-json docs/hand_reach.json [--hands all] [--seeds 3]

A transferred skill is scaled into the hand's workspace (``ias_gym.skills.transfer``). Per
axis of the pen's start frame (x along the pen, y up, z lateral) the workspace is the
largest amplitude of a probe the Theorem-1 expert tracks from every seed. The probe is a
translation out and back along that axis (minimum-jerk, 1 s each way, 0.5 s held between),
with a see-saw over it at a share of the hand's largest tilt (``HandSpec.max_tilt``, 1 Hz;
the shares :data:`TILT_SHARES`). The glove skills combine the two, and a hand must still hold
the pen tilted at the far end. Tracked means held for the whole 3 s episode, an RMS position
error within :data:`SHARE` of the amplitude, and an RMS axis error within :data:`SHARE` of
the see-saw's RMS angle (at least :data:`STILL_DEG`). Amplitudes are
scanned in :data:`STEP_MM` steps up to :data:`MAX_MM` (below the env's 15 mm holding limit);
the largest one tracked below the first one that fails is the reach. The JSON (written
atomically) has every probe and the reach per hand, tilt share and axis;
``HandSpec.reach_by_tilt`` (``ias_gym.sim.hands``) carries the numbers, and a test checks
that they agree with ``docs/hand_reach.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from typing import Any

import numpy as np
from tqdm import tqdm

#: The tracking error allowed, as a share of the probe's amplitude [-].
SHARE = 0.1
#: Amplitudes scanned [mm]: STEP_MM, 2 STEP_MM, ... MAX_MM.
STEP_MM = 2.0
MAX_MM = 14.0
#: The probe's timing [s]: episode, start of the way out, each way, the hold between.
DURATION, START, MOVE, HOLD = 3.0, 0.2, 1.0, 0.5
#: The see-saw's frequency [Hz].
SEESAW_HZ = 1.0
#: The see-saw amplitudes probed, as shares of the hand's largest tilt [-].
TILT_SHARES = (0.25, 0.5, 1.0)
#: The axis error allowed without a see-saw [deg] (the pen kept level while it moves).
STILL_DEG = 0.5


def probe_reference(axis: int, amplitude: float, tilt: float, dt: float = 0.01) -> Any:
    """The probe's :class:`~ias_gym.envs.skill_reference.SkillReference`: ``amplitude`` [m]
    out and back along ``axis`` (0 x, 1 y, 2 z), a see-saw of ``tilt`` [rad] over it."""
    from ias_gym.skills.transfer import motion_reference

    t = np.arange(0.0, DURATION + 1e-9, dt)

    def ramp(t0: float) -> np.ndarray:
        s = np.clip((t - t0) / MOVE, 0.0, 1.0)
        return 10 * s**3 - 15 * s**4 + 6 * s**5

    position = np.zeros((len(t), 3))
    position[:, axis] = amplitude * (ramp(START) - ramp(START + MOVE + HOLD))
    angles = np.zeros((len(t), 2))
    angles[:, 0] = tilt * np.sin(2 * math.pi * SEESAW_HZ * t)
    return motion_reference(position, angles, np.full(len(t), 1.5), dt, name="reach-probe")


def probe(
    hand: str,
    axis: int,
    amplitude: float,
    seed: int,
    tilt_share: float = 1.0,
    disturbance: str = "nominal",
) -> dict[str, Any]:
    """One probe run (the see-saw at ``tilt_share`` of the hand's largest tilt, under a
    class of the robustness suite): held, and the RMS errors against the allowed ones."""
    from ias_gym.robustness import DISTURBANCES
    from ias_gym.sim.hands import get_hand
    from ias_gym.skills.transfer_run import run_transfer

    tilt = tilt_share * get_hand(hand).max_tilt
    reference = probe_reference(axis, amplitude, tilt)
    run, _ = run_transfer(reference, hand, "gt", seed=seed, **DISTURBANCES[disturbance])
    allowed_mm = SHARE * 1000.0 * amplitude
    allowed_deg = max(SHARE * math.degrees(tilt) / math.sqrt(2.0), STILL_DEG)
    return {
        "held": run.held,
        "pos_rms_mm": run.pos_rms_mm,
        "rot_rms_deg": run.rot_rms_deg,
        "tracked": bool(
            run.held and run.pos_rms_mm <= allowed_mm and run.rot_rms_deg <= allowed_deg
        ),
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--hands", default="all", help="comma-separated hands, or all")
    parser.add_argument("--seeds", type=int, default=3, help="reset seeds 0..N-1 per probe")
    parser.add_argument(
        "--disturbance",
        default="nominal",
        help="a class of the robustness suite, e.g. friction_x0.7",
    )
    parser.add_argument("--out-json", required=True, help="the probes and the reach per axis")
    parser.add_argument("--overwrite", action="store_true", help="replace --out-json")
    args = parser.parse_args(argv)
    from ias_gym.outputs import atomic_output, check_output_file
    from ias_gym.robustness import check_classes
    from ias_gym.sim.hands import hand_names

    check_output_file(args.out_json, overwrite=args.overwrite)
    check_classes([args.disturbance])
    hands = hand_names() if args.hands == "all" else args.hands.split(",")
    amplitudes = np.arange(STEP_MM, MAX_MM + 1e-9, STEP_MM)
    jobs = [
        (h, share, a, mm)
        for h in hands
        for share in TILT_SHARES
        for a in range(3)
        for mm in amplitudes
    ]
    probes: list[dict[str, Any]] = []
    reach = {
        h: {str(share): {f"{a}_mm": 0.0 for a in "xyz"} for share in TILT_SHARES} for h in hands
    }
    failed: set[tuple[str, float, int]] = set()
    for hand, share, axis, mm in tqdm(jobs, desc="reach", unit="amplitude"):
        if (hand, share, axis) in failed:
            continue  # the reach ends at the first amplitude that fails
        runs = [
            probe(hand, axis, mm / 1000.0, seed, share, args.disturbance)
            for seed in range(args.seeds)
        ]
        ok = all(r["tracked"] for r in runs)
        probes += [
            {"hand": hand, "tilt_share": share, "axis": "xyz"[axis], "amplitude_mm": mm, **r}
            for r in runs
        ]
        if ok:
            reach[hand][str(share)]["xyz"[axis] + "_mm"] = float(mm)
        else:
            failed.add((hand, share, axis))
    for hand in hands:
        print(hand, reach[hand])
    result = {
        "what": "largest amplitude per axis the expert carries the pen, tilting it (train/"
        "hand_reach.py)",
        "share": SHARE,
        "disturbance": args.disturbance,
        "tilt_shares": list(TILT_SHARES),
        "seeds": args.seeds,
        "reach": reach,
        "probes": probes,
    }
    with atomic_output(args.out_json, overwrite=args.overwrite) as tmp:
        tmp.write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

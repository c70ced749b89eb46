"""Measure how far and how fast each hand's expert tilts and carries the held pen.

    python train/hand_reach.py --out-json docs/hand_reach.json [--hands all] [--seeds 3]

A transferred skill is scaled into the hand's workspace (``ias_gym.skills.transfer``). The
workspace is measured here with the Theorem-1 expert, under the robustness suite's
low-friction class (:data:`DISTURBANCE`): the hand does not know the pen's friction, so the
motions it accepts must hold at 70 % of it too.

1. **Tilt.** A see-saw about the paper's z (no translation) at each of :data:`TILT_HZ`,
   amplitudes scanned down from :data:`TILT_MAX` in :data:`TILT_STEP` steps; the first
   amplitude every seed tracks is the largest tilt at that frequency. The hand's tilt is
   the one at the slowest frequency; its tilt rate is the least peak rate ``2 pi f A_f``
   over the faster ones (a hand whose motors saturate tracks a slow see-saw far beyond a
   fast one: the limit is a rate).
2. **Speed.** The pen's centre oscillates about its start along each axis (no see-saw) at
   each of :data:`SPEED_HZ`, amplitudes scanned down from :data:`SPEED_MAX_MM` in 1 mm
   steps; the hand's speed is the least peak speed ``2 pi f A`` tracked (a hand whose
   motors saturate follows a slow lift but not the quick sway of a see-saw's centre).
3. **Reach.** Per direction of ``REACH_DIRECTIONS`` (both ways along the three axes of the
   pen's start frame, x along the pen, y up, z lateral, and the four diagonals of each
   plane of two axes) the pen's centre goes out (minimum-jerk, 1 s) and is held there to
   the end of the episode, as a lift and place or a tilt ends away from its start; a
   see-saw runs over it at :data:`TILT_SHARES` of the hand's tilt (1 Hz, slower where that
   would exceed the tilt rate). Amplitudes are scanned down from :data:`MAX_MM` in
   :data:`STEP_MM` steps; the first one every seed tracks is the reach.

Tracked means held for the whole 3 s episode, an RMS position error within :data:`SHARE` of
the amplitude (at least :data:`STILL_MM`), and an RMS axis error within :data:`SHARE` of the
see-saw's RMS angle (at least :data:`STILL_DEG`). The scans go down, not up: a scan stops at
its first tracked amplitude and a probe at its first failing seed, so the reach is assumed to
be monotonic in the amplitude. The JSON (written atomically) has every probe and the result
per hand; ``HandSpec.skill_tilt``, ``skill_tilt_rate``, ``skill_speed`` and
``reach_by_tilt`` (``ias_gym.sim.hands``) carry the numbers, and a test checks that they agree with
``docs/hand_reach.json``.
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

from ias_gym.sim.hands import REACH_DIRECTIONS

#: The tracking error allowed, as a share of the probe's amplitude [-].
SHARE = 0.1
#: Translation amplitudes scanned [mm]: MAX_MM, MAX_MM - STEP_MM, ... STEP_MM.
STEP_MM = 2.0
MAX_MM = 14.0
#: Tilt amplitudes scanned [rad]: TILT_MAX, TILT_MAX - TILT_STEP, ... TILT_STEP.
TILT_STEP = 0.025
TILT_MAX = 0.4
#: The see-saw frequencies of the tilt scan [Hz]: from below the persons' slow see-saw
#: (about 0.55 Hz) to above their fast one (about 1.3 Hz).
TILT_HZ = (0.5, 1.0, 2.0)
#: The probe's timing [s]: episode, start of the way out, the way out (then held to the end),
#: and the ramp of the see-saw's amplitude at its start.
DURATION, START, MOVE, RAMP = 3.0, 0.2, 1.0, 0.3
#: Translation amplitudes of the speed scan [mm]: SPEED_MAX_MM, ... 1 mm, at each of
#: SPEED_HZ [Hz] (the persons' fast see-saw moves the pen's centre at about 1.3 Hz).
SPEED_MAX_MM = 8.0
SPEED_HZ = (1.0, 2.0)
#: The see-saw's frequency in the reach scan [Hz] (lower where it would exceed the tilt rate).
SEESAW_HZ = 1.0
#: The see-saw amplitudes of the reach scan, as shares of the hand's tilt [-].
TILT_SHARES = (0.25, 0.5, 0.75, 1.0)
#: The errors allowed however small the probe [deg, mm]: the pen kept level while it moves,
#: and still while it tilts (well below the persons' own spread of 0.8-3.4 deg and 2.3-6.2 mm
#: RMS, ``ias_gym/assets/transfer_tolerances.json``).
STILL_DEG = 0.5
STILL_MM = 0.5
#: The class of the robustness suite the workspace is measured under.
DISTURBANCE = "friction_x0.7"


def probe_reference(
    direction: Sequence[float],
    amplitude: float,
    tilt: float,
    hz: float = SEESAW_HZ,
    sway: bool = False,
) -> Any:
    """The probe's :class:`~ias_gym.envs.skill_reference.SkillReference`: ``amplitude`` [m]
    out along the unit ``direction`` (x, y, z) in :data:`MOVE` s and held there to the end,
    a see-saw of ``tilt`` [rad] at ``hz`` over it; with ``sway``, the centre oscillates
    along ``direction`` at ``hz`` instead (``amplitude`` each way). Oscillations are ramped
    up over the first :data:`RAMP` s after the start."""
    from ias_gym.skills.transfer import motion_reference

    dt = 0.01
    t = np.arange(0.0, DURATION + 1e-9, dt)
    envelope = np.clip((t - START) / RAMP, 0.0, 1.0)
    wave = envelope * np.sin(2 * math.pi * hz * np.maximum(t - START, 0.0))
    s = np.clip((t - START) / MOVE, 0.0, 1.0)
    out = amplitude * (wave if sway else 10 * s**3 - 15 * s**4 + 6 * s**5)
    position = out[:, None] * np.asarray(direction, dtype=float)[None, :]
    angles = np.zeros((len(t), 2))
    angles[:, 0] = tilt * wave
    return motion_reference(position, angles, np.full(len(t), 1.5), dt, name="reach-probe")


def probe(
    hand: str,
    direction: str,
    amplitude: float,
    seed: int,
    tilt: float,
    hz: float,
    disturbance: str = DISTURBANCE,
    sway: bool = False,
) -> dict[str, Any]:
    """One probe run (``amplitude`` [m] along ``direction``, a see-saw of ``tilt`` [rad] at
    ``hz``, or with ``sway`` an oscillation of the centre, under a class of the robustness
    suite): held, and the RMS errors against the allowed ones (of a sway, its RMS)."""
    from ias_gym.robustness import DISTURBANCES
    from ias_gym.sim.hands import reach_direction
    from ias_gym.skills.transfer_run import run_transfer

    reference = probe_reference(reach_direction(direction), amplitude, tilt, hz, sway)
    run, _ = run_transfer(reference, hand, "gt", seed=seed, **DISTURBANCES[disturbance])
    moved_mm = 1000.0 * amplitude / (math.sqrt(2.0) if sway else 1.0)
    allowed_mm = max(SHARE * moved_mm, STILL_MM)
    allowed_deg = max(SHARE * math.degrees(tilt) / math.sqrt(2.0), STILL_DEG)
    tracked = run.held and run.pos_rms_mm <= allowed_mm and run.rot_rms_deg <= allowed_deg
    return {
        "held": run.held,
        "pos_rms_mm": run.pos_rms_mm,
        "rot_rms_deg": run.rot_rms_deg,
        "tracked": bool(tracked),
    }


def scan(
    values: Any,
    run: Any,
    seeds: int,
    record: list[dict[str, Any]],
    **labels: Any,
) -> float:
    """The first of ``values`` (floats, scanned in their order, largest first) that every
    seed tracks (``run(value, seed)``), or 0; each probe is appended to ``record`` with
    ``labels``. A value stops at its first failing seed."""
    for value in values:
        ok = True
        for seed in range(seeds):
            result = run(value, seed)
            record.append({**labels, "value": float(value), "seed": seed, **result})
            if not result["tracked"]:
                ok = False
                break
        if ok:
            return float(value)
    return 0.0


def fastest(scans: Sequence[tuple[float, float]], cap: float) -> float:
    """The fastest a hand is known to follow, from ``(frequency [Hz], largest amplitude
    tracked)`` scans: the least peak rate ``2 pi f A`` over the scans that stopped below
    their ``cap`` (there the rate is what limits the hand), else the largest one shown
    (every scan tracked its largest amplitude: a lower bound)."""
    rates = [2 * math.pi * hz * amplitude for hz, amplitude in scans]
    bound = [r for r, (_, amplitude) in zip(rates, scans, strict=True) if amplitude < cap - 1e-12]
    return min(bound) if bound else max(rates)


def hand_envelope(
    hand: str, seeds: int, disturbance: str, record: list[dict[str, Any]], bar: Any
) -> dict[str, Any]:
    """The tilt, the tilt rate and the reach per tilt share and direction of one hand."""
    tilts = np.round(np.arange(TILT_MAX, TILT_STEP / 2, -TILT_STEP), 6)
    by_hz = {}
    for hz in TILT_HZ:
        by_hz[hz] = scan(
            tilts,
            lambda a, s, hz=hz: probe(hand, "+x", 0.0, s, a, hz, disturbance),
            seeds,
            record,
            hand=hand,
            kind="tilt",
            hz=hz,
        )
        bar.update(1)
    tilt = by_hz[TILT_HZ[0]]
    rate = fastest([(hz, by_hz[hz]) for hz in TILT_HZ[1:]], TILT_MAX)
    sways = np.arange(SPEED_MAX_MM, 0.5, -1.0) / 1000.0
    sway_mm: dict[str, dict[str, float]] = {}
    for hz in SPEED_HZ:
        sway_mm[str(hz)] = {}
        for axis in "xyz":
            found = scan(
                sways,
                lambda m, s, axis=axis, hz=hz: probe(
                    hand, f"+{axis}", m, s, 0.0, hz, disturbance, sway=True
                ),
                seeds,
                record,
                hand=hand,
                kind="speed",
                direction=axis,
                hz=hz,
            )
            sway_mm[str(hz)][axis] = round(1000.0 * found, 6)
            bar.update(1)
    speed = fastest(
        [(hz, sway_mm[str(hz)][axis] / 1000.0) for hz in SPEED_HZ for axis in "xyz"],
        SPEED_MAX_MM / 1000.0,
    )
    amplitudes = np.arange(MAX_MM, STEP_MM / 2, -STEP_MM) / 1000.0
    reach: dict[str, dict[str, float]] = {}
    for share in TILT_SHARES:
        a = share * tilt
        hz = min(SEESAW_HZ, rate / (2 * math.pi * a)) if a > 0 else SEESAW_HZ
        reach[str(share)] = {}
        for name in REACH_DIRECTIONS:
            found = scan(
                amplitudes,
                lambda m, s, name=name, a=a, hz=hz: probe(hand, name, m, s, a, hz, disturbance),
                seeds,
                record,
                hand=hand,
                kind="reach",
                tilt_share=share,
                direction=name,
                hz=hz,
            )
            reach[str(share)][f"{name}_mm"] = round(1000.0 * found, 6)
            bar.update(1)
    return {
        "tilt_rad": tilt,
        "tilt_rate_rad_s": round(rate, 4),
        "tilt_by_hz_rad": {str(hz): v for hz, v in by_hz.items()},
        "speed_m_s": round(speed, 5),
        "sway_by_hz_mm": sway_mm,
        "reach": reach,
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--hands", default="all", help="comma-separated hands, or all")
    parser.add_argument("--seeds", type=int, default=3, help="reset seeds 0..N-1 per probe")
    parser.add_argument(
        "--disturbance",
        default=DISTURBANCE,
        help=f"a class of the robustness suite (default {DISTURBANCE})",
    )
    parser.add_argument("--out-json", required=True, help="the probes and the envelope per hand")
    parser.add_argument("--overwrite", action="store_true", help="replace --out-json")
    args = parser.parse_args(argv)
    from ias_gym.outputs import atomic_output, check_output_file
    from ias_gym.robustness import check_classes
    from ias_gym.sim.hands import hand_names

    check_output_file(args.out_json, overwrite=args.overwrite)
    check_classes([args.disturbance])
    hands = hand_names() if args.hands == "all" else args.hands.split(",")
    probes: list[dict[str, Any]] = []
    envelopes = {}
    steps = len(hands) * (
        len(TILT_HZ) + 3 * len(SPEED_HZ) + len(TILT_SHARES) * len(REACH_DIRECTIONS)
    )
    with tqdm(total=steps, desc="reach", unit="scan") as bar:
        for hand in hands:
            envelopes[hand] = hand_envelope(hand, args.seeds, args.disturbance, probes, bar)
            print(hand, json.dumps(envelopes[hand]), flush=True)
    result = {
        "what": "largest tilt, tilt rate, speed and translation per direction the expert "
        "tracks, tilting the pen (train/hand_reach.py)",
        "share": SHARE,
        "disturbance": args.disturbance,
        "tilt_hz": list(TILT_HZ),
        "tilt_shares": list(TILT_SHARES),
        "directions": list(REACH_DIRECTIONS),
        "seeds": args.seeds,
        "hands": envelopes,
        "probes": probes,
    }
    with atomic_output(args.out_json, overwrite=args.overwrite) as tmp:
        tmp.write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

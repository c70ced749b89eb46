"""Glove calibration over five simulated persons: accuracy, training time, inference cost.

Run: ``python bench/bench_glove.py [--persons p1 p2 p3 p4 p5] [--readings 2000]``. For each
person (:meth:`PersonParams.sample`) one calibration session is recorded and split 80/20,
the shipped ANN calibration, the paper's index 2-10-3 variant and the linear least-squares
baseline are trained on the same readings (:func:`calibrate_person`) and evaluated on the
held-out ones. Prints, measured in this one run:

1. per person: held-out joint RMS [deg] over all joints and over pinch poses only, and the
   thumb-index fingertip gap error in pinch [mm], for ANN / paper ANN / linear; the ANN's
   training time [s];
2. the means, and the issue's targets (ANN RMS <= 2 deg on average, linear/ANN pinch RMS
   >= 3, ANN pinch gap <= 3 mm, training <= 10 s per person, inference <= 20 us);
3. numpy inference per single reading (``Calibration.predict`` on a ``(10,)`` array, as a
   control loop calls it): median and p90 [us] for the ANN and the linear calibration,
   loaded from a saved profile, and the batch cost per reading.
"""

from __future__ import annotations

import argparse
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ias_gym.glove.calibration import DEFAULT_READINGS, Calibration
from ias_gym.glove.hand import PersonParams
from ias_gym.glove.profile import Profile, load_profile, save_profile

TARGET_RMS_DEG = 2.0
TARGET_PINCH_RATIO = 3.0
TARGET_GAP_MM = 3.0
TARGET_TRAIN_S = 10.0
TARGET_INFERENCE_US = 20.0


def single_reading_us(calibration: Calibration, psi: np.ndarray, calls: int) -> np.ndarray:
    """Microseconds per ``predict`` call on one ``(10,)`` reading, ``calls`` times."""
    times = np.empty(calls)
    rows = psi[np.arange(calls) % len(psi)]
    clock = time.perf_counter_ns
    for k in range(calls):
        reading = rows[k]
        t0 = clock()
        calibration.predict(reading)
        times[k] = clock() - t0
    return times / 1e3


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--persons", nargs="+", default=["p1", "p2", "p3", "p4", "p5"])
    parser.add_argument("--readings", type=int, default=DEFAULT_READINGS)
    parser.add_argument("--calls", type=int, default=20000, help="single-reading predictions")
    args = parser.parse_args()

    from ias_gym.glove.training import calibrate_person

    print(f"python {platform.python_version()}, numpy {np.__version__}, {platform.machine()}")
    header = (
        f"{'person':<7} {'scale':>5} | {'all RMS [deg]':^20} | {'pinch RMS [deg]':^20} | "
        f"{'pinch gap [mm]':^20} | {'ratio':>5} {'train':>6}"
    )
    sub = (
        f"{'':<7} {'':>5} | "
        + " | ".join([f"{'ANN':>6} {'2-10-3':>6} {'lin':>6}"] * 3)
        + f" | {'lin/ANN':>5} {'[s]':>6}"
    )
    print(header)
    print(sub)
    rows = []
    last = None
    for pid in args.persons:
        person = PersonParams.sample(pid)
        run = calibrate_person(person, n_readings=args.readings)
        m = run.metrics
        keys = ("ann", "paper_ann", "linear")
        ratio = m["linear"].pinch_rms_deg / m["ann"].pinch_rms_deg
        rows.append(
            [m[k].rms_deg for k in keys]
            + [m[k].pinch_rms_deg for k in keys]
            + [m[k].pinch_gap_mm for k in keys]
            + [ratio, run.report.seconds]
        )
        r = rows[-1]
        print(
            f"{pid:<7} {person.hand_scale:>5.2f} | {r[0]:>6.2f} {r[1]:>6.2f} {r[2]:>6.2f} | "
            f"{r[3]:>6.2f} {r[4]:>6.2f} {r[5]:>6.2f} | {r[6]:>6.2f} {r[7]:>6.2f} {r[8]:>6.2f} | "
            f"{r[9]:>5.1f} {r[10]:>6.2f}",
            flush=True,
        )
        last = run
    a = np.array(rows).mean(axis=0)
    print(
        f"{'mean':<7} {'':>5} | {a[0]:>6.2f} {a[1]:>6.2f} {a[2]:>6.2f} | "
        f"{a[3]:>6.2f} {a[4]:>6.2f} {a[5]:>6.2f} | {a[6]:>6.2f} {a[7]:>6.2f} {a[8]:>6.2f} | "
        f"{a[9]:>5.1f} {a[10]:>6.2f}"
    )
    assert last is not None

    # Inference: the ANN and linear calibrations of the last person, through a profile file.
    with tempfile.TemporaryDirectory() as tmp:
        timings = {}
        psi = last.held_out.psi
        for name in ("ann", "linear"):
            path = Path(tmp) / f"{name}.json"
            profile = Profile(last.person.person_id, "bench", last.models[name], last.metrics[name])
            calibration = load_profile(save_profile(profile, path)).calibration
            single_reading_us(calibration, psi, 2000)  # warm up
            us = single_reading_us(calibration, psi, args.calls)
            t0 = time.perf_counter()
            for _ in range(20):
                calibration.predict(psi)
            batch = (time.perf_counter() - t0) / (20 * len(psi)) * 1e6
            timings[name] = (float(np.median(us)), float(np.percentile(us, 90)), batch)
    print()
    print(
        f"numpy inference, one (10,) reading per call, {args.calls} calls ({last.person.person_id})"
    )
    print(f"{'model':<8} {'median [us]':>12} {'p90 [us]':>9} {'batch [us/reading]':>19}")
    for name, (med, p90, batch) in timings.items():
        print(f"{name:<8} {med:>12.2f} {p90:>9.2f} {batch:>19.3f}")

    checks = {
        f"ANN held-out RMS, mean over persons {a[0]:.2f} deg <= {TARGET_RMS_DEG}": a[0]
        <= TARGET_RMS_DEG,
        f"linear/ANN pinch RMS >= {TARGET_PINCH_RATIO} for every person (min "
        f"{min(r[9] for r in rows):.1f})": min(r[9] for r in rows) >= TARGET_PINCH_RATIO,
        f"ANN pinch gap error, mean {a[6]:.2f} mm (max {max(r[6] for r in rows):.2f}) "
        f"<= {TARGET_GAP_MM}": a[6] <= TARGET_GAP_MM,
        f"training <= {TARGET_TRAIN_S} s per person (max {max(r[10] for r in rows):.2f} s)": max(
            r[10] for r in rows
        )
        <= TARGET_TRAIN_S,
        f"ANN inference median {timings['ann'][0]:.1f} us <= {TARGET_INFERENCE_US}": timings["ann"][
            0
        ]
        <= TARGET_INFERENCE_US,
    }
    print()
    for text, ok in checks.items():
        print(f"[{'ok' if ok else 'MISSED'}] {text}")
    return 0 if all(checks.values()) else 1


if __name__ == "__main__":
    sys.exit(main())

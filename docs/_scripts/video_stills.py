"""Stills of a video for the docs: frames at given times, stacked top to bottom, as a PNG.

    python docs/_scripts/video_stills.py out/assist_stops.mp4 --times 1.8 4.0 --scale 0.75 \
        --out docs/img/assist_stops.png

A time past the video's end takes its last frame. The videos of ``ias-gym assist demo`` show
every second control step of 10 ms (``--frame-s`` 0.02), the reset first.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import imageio.v3 as iio
import numpy as np
from PIL import Image


def main(argv: list[str] | None = None) -> int:
    """Write the stills (arguments: ``--help``)."""
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("video", help="the video to read")
    ap.add_argument("--times", type=float, nargs="+", required=True, help="times [s]")
    ap.add_argument("--frame-s", type=float, default=0.02, help="time between frames [s]")
    ap.add_argument("--scale", type=float, default=1.0, help="size of the PNG [-]")
    ap.add_argument("--out", required=True, help="the PNG written (replaced)")
    args = ap.parse_args(argv)
    frames = iio.imread(args.video)
    picks = [frames[min(round(t / args.frame_s), len(frames) - 1)] for t in args.times]
    image = Image.fromarray(np.concatenate(picks, axis=0))
    if args.scale != 1.0:
        size = (round(image.width * args.scale), round(image.height * args.scale))
        image = image.resize(size, Image.Resampling.LANCZOS)
    image.save(Path(args.out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

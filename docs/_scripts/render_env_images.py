"""Render one picture of every registered env for its documentation page.

Each env is made with ``render_mode="rgb_array"`` and reset with seed 0 (the glove worlds then
step with the zero action until the person has closed the pinch), rendered once
and written, 320 x 240, as a palette PNG to ``docs/_static/envs/<id>.png``. The pictures
are committed, so ``make docs`` never renders; run this again when a scene changes:

    MUJOCO_GL=egl .venv/bin/python docs/_scripts/render_env_images.py [ID ...]

``IAS-GloveHardware-v0`` is rendered on python-can's virtual bus against the in-process
glove emulator (the ``[hardware]`` extra).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent))
import env_pages

OUT = env_pages.DOCS / "_static" / "envs"
SIZE = (320, 240)
#: Zero-action steps before the frame: the glove worlds' pinch closes in about 0.7 s.
STEPS = {"IAS-GloveGrasp-v0": 120, "IAS-GloveAssist-v0": 120, "IAS-GloveHardware-v0": 120}


@contextlib.contextmanager
def device_for(env_id: str) -> Iterator[dict[str, Any]]:
    """The keyword arguments an id needs to run here (a glove emulator for the CAN env)."""
    if env_id != "IAS-GloveHardware-v0":
        yield {}
        return
    from ias_gym.hardware import GloveEmulator

    channel = f"ias-docs-{os.getpid()}"
    with GloveEmulator(channel=channel, rate_hz=500, watchdog_timeout=0.5):
        yield {"channel": channel, "watchdog_timeout": 0.5, "realtime": False}


def frame(env_id: str) -> Image.Image:
    """One rendered frame of ``env_id``, resized to :data:`SIZE`."""
    import gymnasium as gym

    import ias_gym  # noqa: F401  (registers the ids)

    with device_for(env_id) as kwargs:
        env = gym.make(env_id, render_mode="rgb_array", **kwargs)
        try:
            env.reset(seed=0)
            zero = np.zeros(env.action_space.shape or ())
            for _ in range(STEPS.get(env_id, 0)):
                env.step(zero)
            rgb = env.render()
        finally:
            env.close()
    image = Image.fromarray(np.asarray(rgb, dtype=np.uint8))
    return image.resize(SIZE, Image.Resampling.LANCZOS)


def save(image: Image.Image, path: Path) -> None:
    """A 128-colour palette PNG: a few tens of kB instead of a few hundred."""
    image.quantize(colors=128, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)


def main(argv: Sequence[str] | None = None) -> int:
    """Render the named ids (default: every registered one)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("ids", nargs="*", help="env ids (default: all registered)")
    args = parser.parse_args(argv)
    ids = args.ids or [e.env_id for e in env_pages.registered()]
    OUT.mkdir(parents=True, exist_ok=True)
    for env_id in ids:
        path = OUT / f"{env_id}.png"
        save(frame(env_id), path)
        print(f"{path} {path.stat().st_size // 1024} kB")
    return 0


if __name__ == "__main__":
    sys.exit(main())

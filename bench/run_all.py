"""Run every benchmark in this folder, one after another (``make bench``)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

BENCHES = (
    "bench_internal_forces.py",
    "bench_envs.py",
    "bench_vector.py",
    "bench_controller.py",
    "bench_glove.py",
    "bench_glove_loop.py",
    "bench_glove_speed.py",
    "bench_shadow_adroit.py",
)

if __name__ == "__main__":
    here = Path(__file__).parent
    for name in BENCHES:
        print(f"\n== {name}", flush=True)
        subprocess.run([sys.executable, str(here / name)], check=True)

"""Learning curves of DAgger (and SAC) runs: development success against env steps and
wall-clock time.

Reads results files of ``train/dagger.py`` run with ``--curve-episodes N`` (each iteration's
learner judged on ``N`` development episodes of the training distribution, whose seeds and
dynamics draws no training episode used), or of ``train/sac_demos.py`` with
``--curve-every STEPS``, and draws one line per run, one row per env: success
against the env steps collected so far (expert and learner) and against the wall-clock time of
collecting and cloning so far (evaluation excluded). The BC baseline of a run, judged on the
same episodes, is a marker at its own steps and time.

    python train/dagger_curves.py out/dagger_ens/*.json --out docs/img/dagger_curves.png
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any


def build_parser() -> argparse.ArgumentParser:
    """Command-line options."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument(
        "results", nargs="+", metavar="RUN.json", help="train/dagger.py or sac_demos.py results"
    )
    parser.add_argument("--out", required=True, metavar="PATH.png", help="figure to write")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing figure")
    return parser


def load_runs(paths: Sequence[Path]) -> list[dict[str, Any]]:
    """The runs with a learning curve, in the order given.

    Raises:
        ValueError: a file that is not a train/dagger.py result or has no curve.
    """
    runs = []
    for path in paths:
        try:
            run = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise ValueError(f"{path}: not a readable JSON file ({exc})") from None
        if not isinstance(run, dict) or "env" not in run or "development_curve" not in run:
            raise ValueError(f"{path}: not a results file of train/dagger.py or train/sac_demos.py")
        points = run.get("development_curve") or []
        if not points or "env_steps" not in points[0]:
            raise ValueError(
                f"{path}: no learning curve with env steps; run train/dagger.py with "
                "--curve-episodes N"
            )
        runs.append(run)
    return runs


def label(run: dict[str, Any]) -> str:
    """The method's name in the legend."""
    if run.get("learner") == "sac_demos":
        return "SAC + demonstrations"
    size = int(run.get("ensemble", 1))
    return "DAgger" if size == 1 else f"DAgger, ensemble of {size}"


def plot(runs: Sequence[dict[str, Any]], out: Path) -> None:
    """Draw the curves (module docstring) into ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    envs = sorted({run["env"] for run in runs})
    methods = sorted({label(run) for run in runs})
    colours = {m: f"C{i}" for i, m in enumerate(methods)}
    fig, axes = plt.subplots(len(envs), 2, figsize=(10, 3.4 * len(envs)), squeeze=False)
    for row, env in zip(axes, envs, strict=True):
        for run in (r for r in runs if r["env"] == env):
            colour = colours[label(run)]
            points = run["development_curve"]
            for ax, key, scale in ((row[0], "env_steps", 1e-3), (row[1], "wall_time_s", 1 / 60)):
                x = [p[key] * scale for p in points]
                y = [100 * p["success_rate"] for p in points]
                low = [100 * p["ci95_low"] for p in points]
                high = [100 * p["ci95_high"] for p in points]
                ax.plot(x, y, "-o", color=colour, ms=3, lw=1.2, label=label(run))
                ax.fill_between(x, low, high, color=colour, alpha=0.08, lw=0)
                bc = run.get("bc_development_point")
                if bc:
                    ax.plot(
                        bc[key] * scale,
                        100 * bc["success_rate"],
                        "s",
                        color=colour,
                        mfc="white",
                        ms=6,
                        label=label(run).replace("DAgger", "BC"),
                    )
        row[0].set_ylabel(f"{env}\ndevelopment success [%]")
        row[0].set_xlabel("env steps collected [thousands]")
        row[1].set_xlabel("wall-clock of training [min]")
        for ax in row:
            ax.set_ylim(-3, 103)
            ax.grid(alpha=0.3)
    handles, names = axes[0][0].get_legend_handles_labels()
    unique = dict(zip(names, handles, strict=True))
    fig.legend(unique.values(), unique.keys(), loc="lower center", ncol=len(unique), frameon=False)
    fig.suptitle(
        "Learners under randomised dynamics: one line per training seed "
        "(band: 95 % Wilson interval; squares: BC on as many expert labels)",
        fontsize=10,
    )
    fig.tight_layout(rect=(0, 0.06, 1, 0.97))
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    tmp.replace(out)


def main(argv: Sequence[str] | None = None) -> int:
    """Read the runs, draw the figure."""
    args = build_parser().parse_args(argv)
    out = Path(args.out)
    if out.suffix != ".png":
        print(f"error: --out must end in .png, got {out}", file=sys.stderr)
        return 2
    if out.exists() and not args.overwrite:
        print(f"error: {out} exists; pass --overwrite to replace it", file=sys.stderr)
        return 2
    try:
        runs = load_runs([Path(p) for p in args.results])
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    plot(runs, out)
    print(f"wrote {out} ({len(runs)} runs)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

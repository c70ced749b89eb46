"""The assistance figure: success per impairment without and with each assistant.

Reads the JSON files `train/assist_table.py` wrote and draws grouped bars, one group per
impairment: unassisted, then every assistant of every table.

    PYTHONPATH=$PWD python train/assist_figure.py out/table_phase.json out/table_oracle.json \\
        --out docs/img/assistance.png
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

#: Keys of an assist_table JSON that are not assistants.
NOT_ASSISTANTS = {"set", "population", "persons", "skills", "seed", "operator", "switch_latency"}


def main(argv: list[str] | None = None) -> int:
    """Draw the figure (arguments: ``--help``)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("tables", nargs="+", help="assist_table.py JSON files")
    parser.add_argument("--out", default="docs/img/assistance.png", help="the PNG")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    args = parser.parse_args(argv)
    out = Path(args.out)
    if out.exists() and not args.overwrite:
        print(f"error: {out} exists; pass --overwrite", file=sys.stderr)
        return 2
    results: dict[str, dict[str, Any]] = {}
    title = ""
    for name in args.tables:
        try:
            table = json.loads(Path(name).read_text())
        except (OSError, ValueError) as exc:
            print(f"error: {name} is not a readable assist_table JSON ({exc})", file=sys.stderr)
            return 2
        if "population" in table:
            n, seed = table["population"]
            title = f"{n} persons of population seed {seed} ({table.get('set', '?')})"
        results.update({k: v for k, v in table.items() if k not in NOT_ASSISTANTS})
    if not results:
        print("error: the tables hold no assistant", file=sys.stderr)
        return 2

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    first = next(iter(results.values()))
    impairments = list(first)
    # each bar a rate (Rate.to_dict, with its 95 % interval), or a bare share (older tables)
    series = {
        "unassisted": [
            first[i].get("unassisted") or first[i]["success_unassisted"] for i in impairments
        ]
    }
    for name, rows in results.items():
        # assist_table.py names an assistant on the oracle intent without a recogniser
        label = name.replace("+", " + ") if "+" in name else f"{name} + oracle"
        series[label] = [
            rows[i].get("assisted") or rows[i]["success_assisted"] for i in impairments
        ]
    fig, ax = plt.subplots(figsize=(10, 3.6))
    width = 0.8 / len(series)
    for k, (name, values) in enumerate(series.items()):
        xs = [i + (k - (len(series) - 1) / 2) * width for i in range(len(impairments))]
        rates = [v if isinstance(v, dict) else {"success_rate": v or 0.0} for v in values]
        heights = [100 * r["success_rate"] for r in rates]
        errors = [
            [h - 100 * r.get("ci95_low", h / 100) for h, r in zip(heights, rates, strict=True)],
            [100 * r.get("ci95_high", h / 100) - h for h, r in zip(heights, rates, strict=True)],
        ]
        ax.bar(xs, heights, width, label=name, yerr=errors, capsize=2)
    ax.axhline(90, color="grey", linestyle=":", linewidth=1)  # the goal assisted
    ax.axhline(50, color="grey", linestyle=":", linewidth=1)
    # sessions without a reference are left out, so each impairment has its own count
    ax.set_xticks(
        range(len(impairments)),
        [f"{i.replace('_', ' ')}\n({first[i]['sessions']} sessions)" for i in impairments],
    )
    ax.set_ylabel("success [%]")
    ax.set_ylim(0, 105)
    ax.set_title(f"{title}; bars: 95 % intervals")
    ax.legend(fontsize=8, ncol=len(series), loc="upper center", bbox_to_anchor=(0.5, -0.2))
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

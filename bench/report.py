"""A benchmark run's tables: printed as Markdown and, with ``--json``, kept as a result file.

Every script in ``bench/`` builds one :class:`Report`, adds its tables row by row (each row
is printed as it is measured) and its goal checks, and ends with :meth:`Report.finish`.
``--json PATH`` writes the run (machine, versions, command, tables, checks) atomically;
``bench/run_all.py`` writes one file per script into ``docs/benchmarks/``, and the docs build
renders those into the benchmarks page (``docs/_scripts/result_tables.py``), so the page
shows the latest run's numbers and nothing typed by hand.

    report = Report.start(parser)          # adds --json/--overwrite, parses, checks the path
    table = report.table("title", ["env", "median [us]"])
    table.row("IAS-PenSlide-v0", "317")
    report.check("env.step / mj_step <= 1.15", ratio <= 1.15)
    report.finish()
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ias_gym.errors import IasGymError
from ias_gym.outputs import atomic_output, check_output_file

SCHEMA = "ias-gym/bench-v1"


def machine() -> dict[str, Any]:
    """The facts a timing depends on: CPU, cores, load, Python and library versions."""
    import mujoco
    import numpy as np

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    return {
        "cpu": platform.processor() or platform.machine(),
        "cores": os.cpu_count(),
        "load_average_1min": None if load is None else round(load, 2),
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
        "numpy": np.__version__,
    }


@dataclass
class Table:
    """One table of a run: a title, a header and rows of formatted cells."""

    title: str
    header: list[str]
    rows: list[list[str]] = field(default_factory=list)

    def row(self, *cells: object) -> None:
        """Add a row (cells formatted with ``str``) and print it."""
        if len(cells) != len(self.header):
            raise ValueError(f"{self.title}: {len(cells)} cells for {len(self.header)} columns")
        self.rows.append([str(c) for c in cells])
        print("| " + " | ".join(self.rows[-1]) + " |", flush=True)

    def as_dict(self) -> dict[str, Any]:
        return {"title": self.title, "header": self.header, "rows": self.rows}


@dataclass
class Report:
    """The tables and goal checks of one benchmark run."""

    script: str
    arguments: list[str]
    json_path: Path | None
    overwrite: bool
    tables: list[Table] = field(default_factory=list)
    checks: list[dict[str, Any]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @classmethod
    def start(
        cls, parser: argparse.ArgumentParser, argv: Sequence[str] | None = None
    ) -> tuple[Report, argparse.Namespace]:
        """Add ``--json``/``--overwrite`` to ``parser``, parse, check the output path before
        any work, print the machine line; returns the report and the parsed arguments."""
        parser.add_argument("--json", metavar="FILE.json", help="also write the run here")
        parser.add_argument("--overwrite", action="store_true", help="replace an existing --json")
        arguments = list(sys.argv[1:] if argv is None else argv)
        args = parser.parse_args(arguments)
        path = None
        if args.json is not None:
            try:
                path = check_output_file(
                    args.json, overwrite=args.overwrite, suffixes=(".json",), what="--json"
                )
            except IasGymError as error:
                parser.exit(2, f"{parser.prog}: {error}\n")
        kept = _without_output_options(arguments)
        report = cls(Path(sys.argv[0]).name, kept, path, args.overwrite)
        facts = machine()
        print(
            f"machine: {facts['cpu']}, {facts['cores']} cores, load {facts['load_average_1min']}, "
            f"python {facts['python']}, mujoco {facts['mujoco']}, numpy {facts['numpy']}",
            flush=True,
        )
        return report, args

    def table(self, title: str, header: Sequence[str]) -> Table:
        """Start a table; its rows print as they are added."""
        table = Table(title, list(header))
        self.tables.append(table)
        print(f"\n{title}\n\n| " + " | ".join(table.header) + " |", flush=True)
        print("|" + "---|" * len(table.header), flush=True)
        return table

    def check(self, goal: str, met: bool, measured: str = "") -> bool:
        """Record a goal and whether this run met it; returns ``met``."""
        self.checks.append({"goal": goal, "met": bool(met), "measured": measured})
        print(f"[{'ok' if met else 'MISSED'}] {goal}" + (f" ({measured})" if measured else ""))
        return bool(met)

    def note(self, text: str) -> None:
        """A sentence about this run (a setting, a caveat), printed and kept."""
        self.notes.append(text)
        print(text, flush=True)

    def as_dict(self) -> dict[str, Any]:
        return {
            "schema": SCHEMA,
            "script": self.script,
            "command": " ".join(["python", f"bench/{self.script}", *self.arguments]),
            "date_utc": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M"),
            "machine": machine(),
            "tables": [t.as_dict() for t in self.tables],
            "checks": self.checks,
            "notes": self.notes,
        }

    def finish(self) -> None:
        """Write the run to ``--json`` (atomically), if one was given."""
        if self.json_path is None:
            return
        with atomic_output(self.json_path, overwrite=self.overwrite) as tmp:
            tmp.write_text(json.dumps(self.as_dict(), indent=1) + "\n")
        print(f"wrote {self.json_path}", file=sys.stderr)


def _without_output_options(arguments: list[str]) -> list[str]:
    """The arguments minus ``--json PATH`` and ``--overwrite`` (the command that reproduces
    the numbers, not the file)."""
    kept, skip = [], False
    for a in arguments:
        if skip:
            skip = False
        elif a == "--json":
            skip = True
        elif not (a.startswith("--json=") or a == "--overwrite"):
            kept.append(a)
    return kept

"""Docstring fixes for autodoc, so that the package's docstrings read as reST.

- An env class's docstring is written in Gymnasium's Markdown sections (``## Rewards``);
  its rendered form is the env's own page (``env_pages.py``), so the API page shows the
  summary line and links there.
- ``|x|`` (an absolute value or a norm) would be a reST substitution: the bars are escaped
  outside inline literals.
- A ``Returns:`` section that names several values, one ``name: text`` line each (as
  ``Args:`` does), becomes a rubric and a list: napoleon reads ``Returns:`` as one value.
"""

from __future__ import annotations

import re
from typing import Any

#: ``|text|`` with no space after the first bar, outside backquotes.
BARS = re.compile(r"(?<![\\`|])\|(?=[^\s|`])([^|`\n]*?[^\s|\\])\|(?![|_])")
LITERAL = re.compile(r"(``.*?``|`[^`]*`)")


def escape_bars(line: str) -> str:
    """``|r|`` as ``\\|r\\|`` wherever it is not inside an inline literal."""
    pieces = LITERAL.split(line)
    for i in range(0, len(pieces), 2):
        pieces[i] = BARS.sub(r"\\|\1\\|", pieces[i])
    return "".join(pieces)


#: A line that names one returned value: ``r: centre-of-mass position [m]``.
NAMED = re.compile(r"^[A-Za-z_*][\w, ()*]*: ")


def indent(line: str) -> int:
    """The number of leading spaces."""
    return len(line) - len(line.lstrip(" "))


def named_returns(lines: list[str]) -> list[str]:
    """Every ``Returns:`` block of two or more named values as a rubric and a list."""
    out: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.strip() != "Returns:":
            out.append(line)
            i += 1
            continue
        base = indent(line)
        j = i + 1
        while j < len(lines) and (not lines[j].strip() or indent(lines[j]) > base):
            j += 1
        block = lines[i + 1 : j]
        while block and not block[-1].strip():
            block.pop()
        body = [b for b in block if b.strip()]
        item = min((indent(b) for b in body), default=0)
        items = [b for b in body if indent(b) == item]
        if len(items) < 2 or not all(NAMED.match(b.strip()) for b in items):
            out.append(line)
            i += 1
            continue
        pad = " " * base
        out += [f"{pad}.. rubric:: Returns", ""]
        for b in block:
            if not b.strip():
                out.append("")
            elif indent(b) == item:
                out.append(f"{pad}- {b.strip()}")
            else:
                out.append(f"{pad}  {b.strip()}")
        out.append("")
        i = j
    return out


def env_page(obj: Any) -> str | None:
    """The registered id whose class is ``obj``, or a subclass of it (an env registered
    through a thin subclass, e.g. the one that injects the skill DB), or ``None``."""
    import importlib

    from ias_gym import registration

    specs = {**registration.ENV_SPECS, **registration.HARDWARE_ENV_SPECS}
    for env_id, (entry, _) in specs.items():
        module, _, qualname = entry.partition(":")
        cls = getattr(importlib.import_module(module), qualname, None)
        if cls is obj:
            return env_id
        try:
            if isinstance(cls, type) and isinstance(obj, type) and issubclass(cls, obj):
                return env_id
        except TypeError:  # obj is a protocol that cannot be checked: no env's base
            continue
    return None


def process(app: Any, what: str, name: str, obj: Any, options: Any, lines: list[str]) -> None:
    """autodoc-process-docstring: rewrite ``lines`` in place."""
    env_id = env_page(obj) if what == "class" else None
    if env_id is not None and any(line.startswith("## ") for line in lines):
        summary = lines[: lines.index("")] if "" in lines else lines[:1]
        lines[:] = [
            *summary,
            "",
            f"Its observation and action spaces, rewards, episode end and arguments: "
            f":doc:`/envs/{env_id}`.",
            "",
        ]
        return
    lines[:] = named_returns([escape_bars(line) for line in lines])

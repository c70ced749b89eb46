"""One documentation page per registered ``IAS-*`` env id, written from its class docstring.

The env classes document themselves in Gymnasium's sections (``## Description``, ``## Action
Space``, ... ``## Version History``; ``tests/test_env_docstrings.py`` holds them to it). This
script turns each docstring into a MyST page, ``docs/envs/<id>.md``: the id, the env's
picture (``docs/_static/envs/<id>.png``, made by ``render_env_images.py``), a table of what
the registry says (class, episode length, the id's own keyword arguments) with the spaces
the docstring states, then the docstring's sections. Sphinx roles in the docstring
(``:class:`X```) become MyST roles whose targets are qualified with the class's module, so
they link into the API pages.

The pages are committed (the README links to them on GitHub) and rewritten by every
``make docs``; ``tests/test_docs.py`` fails when a committed page differs from its docstring.

    python docs/_scripts/env_pages.py   # rewrite docs/envs/*.md
"""

from __future__ import annotations

import importlib
import inspect
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

DOCS = Path(__file__).resolve().parents[1]

#: ``:role:`target``` and ``:py:role:`target``` in a docstring.
ROLE = re.compile(r":(?:py:)?(class|func|meth|attr|data|mod|exc|obj|const):`(~?)([^`]+)`")
#: A Google-style section at the left margin (``Attributes:``), its items indented below.
GOOGLE_SECTION = re.compile(r"^(Attributes|Args|Note|Notes|Example|Examples):\s*$")
#: The first inline literal of a section: the space's repr, e.g. ``Box(-1, 1, (12,))``.
LITERAL = re.compile(r"``([^`]+)``")


@dataclass(frozen=True)
class EnvEntry:
    """A registered id and what the registry says about it."""

    env_id: str
    entry_point: str
    max_episode_steps: int
    kwargs: dict[str, Any]
    needs_device: bool

    @property
    def env_class(self) -> type:
        """The class behind the entry point (imports its module)."""
        module, name = self.entry_point.split(":")
        cls: type = getattr(importlib.import_module(module), name)
        return cls


def registered() -> list[EnvEntry]:
    """Every id of :mod:`ias_gym.registration`, in its order (the simulated ones first)."""
    from ias_gym import registration

    entries = []
    for specs, device in ((registration.ENV_SPECS, False), (registration.HARDWARE_ENV_SPECS, True)):
        for env_id, (entry_point, steps) in specs.items():
            kwargs = dict(registration.ENV_KWARGS.get(env_id, {}))
            entries.append(EnvEntry(env_id, entry_point, steps, kwargs, device))
    return entries


def own_docstring(cls: type) -> str:
    """The class's own docstring (not an inherited one), dedented."""
    doc = cls.__dict__.get("__doc__")
    if not doc:
        raise ValueError(f"{cls.__module__}.{cls.__qualname__} has no docstring of its own")
    return inspect.cleandoc(doc)


def qualify(role: str, target: str, cls: type, module: ModuleType) -> str:
    """A role's target as a full dotted name: on the class (an attribute or method named
    alone is the class's, set in ``__init__`` or not), else in its module."""
    if target.startswith("ias_gym."):
        return target
    head = target.split(".", 1)[0]
    if (
        hasattr(cls, head)
        or (role in ("attr", "meth") and "." not in target)
        or head in getattr(cls, "__annotations__", {})
    ):
        return f"{cls.__module__}.{cls.__qualname__}.{target}"
    if hasattr(module, head):
        return f"{module.__name__}.{target}"
    return target


def myst_roles(text: str, cls: type) -> str:
    """Sphinx roles as MyST roles, targets qualified (shown by their last part)."""
    module = sys.modules[cls.__module__]

    def replace(match: re.Match[str]) -> str:
        role, tilde, target = match.groups()
        full = qualify(role, target, cls, module)
        short = "~" if tilde or full != target else ""
        return f"{{py:{role}}}`{short}{full}`"

    return ROLE.sub(replace, text)


def google_sections(doc: str) -> str:
    """``Attributes:`` and its indented ``name: text`` items as a heading and a list."""
    out: list[str] = []
    in_section = False
    for line in doc.splitlines():
        match = GOOGLE_SECTION.match(line)
        if match:
            out += [f"## {match.group(1)}", ""]
            in_section = True
        elif in_section and line.startswith("    ") and not line.startswith("        "):
            name, _, rest = line.strip().partition(": ")
            names = ", ".join(f"``{n.strip()}``" for n in name.split(","))
            out.append(f"- {names}: {rest}")
        elif in_section and line.startswith("        "):
            out.append("  " + line.strip())
        else:
            in_section = in_section and not line.strip() == "" and line.startswith(" ")
            out.append(line)
    return "\n".join(out)


def sections(doc: str) -> tuple[str, dict[str, str]]:
    """The docstring's summary and its ``## `` sections by title."""
    summary, _, body = doc.partition("\n## ")
    parts: dict[str, str] = {}
    for chunk in ("## " + body).split("\n## ") if body else []:
        title, _, text = chunk.removeprefix("## ").partition("\n")
        parts[title.strip()] = text.strip()
    return summary.strip(), parts


def first_literal(text: str) -> str:
    """The section's first inline literal, else ``-``."""
    match = LITERAL.search(text)
    return f"``{match.group(1)}``" if match else "-"


def page(entry: EnvEntry) -> str:
    """The MyST page of one id."""
    cls = entry.env_class
    doc = myst_roles(google_sections(own_docstring(cls)), cls)
    summary, parts = sections(doc)
    name = f"{cls.__module__}.{cls.__qualname__}"
    kwargs = ", ".join(f"``{k}={v!r}``" for k, v in entry.kwargs.items()) or "none"
    picture = DOCS / "_static" / "envs" / f"{entry.env_id}.png"
    lines = [
        f"# {entry.env_id}",
        "",
        "<!-- generated by docs/_scripts/env_pages.py from the class docstring: edit the",
        "     docstring, then run `make docs` -->",
        "",
        summary,
        "",
    ]
    if picture.exists():
        lines += [f"![{entry.env_id}](../_static/envs/{entry.env_id}.png)", ""]
    lines += [
        "| | |",
        "|---|---|",
        f'| make | ``gym.make("{entry.env_id}")`` after ``import ias_gym`` |',
        f"| class | {{py:class}}`~{name}` |",
        f"| action space | {first_literal(parts.get('Action Space', ''))} |",
        f"| observation space | {first_literal(parts.get('Observation Space', ''))} |",
        f"| episode | at most {entry.max_episode_steps} steps |",
        f"| keyword arguments of the id | {kwargs} |",
    ]
    if entry.needs_device:
        lines.append(
            "| needs | a glove on a CAN bus, its emulator or a recorded session "
            "(the ``[hardware]`` extra) |"
        )
    lines.append("")
    for title, text in parts.items():
        lines += [f"## {title}", "", text, ""]
    return "\n".join(lines).rstrip() + "\n"


def index(entries: list[EnvEntry]) -> str:
    """The list of every id with its summary line."""
    lines = [
        "# Environments",
        "",
        "<!-- generated by docs/_scripts/env_pages.py -->",
        "",
        "Every id is registered by ``import ias_gym``. Units are SI and every pen task works in",
        "the paper's frame: x along the pen, y up, z lateral.",
        "",
        "| id | what |",
        "|---|---|",
    ]
    for e in entries:
        summary = sections(myst_roles(own_docstring(e.env_class), e.env_class))[0]
        lines.append(f"| [{e.env_id}]({e.env_id}.md) | {' '.join(summary.split())} |")
    lines += ["", "```{toctree}", ":hidden:", ""]
    lines += [e.env_id for e in entries]
    lines += ["```", ""]
    return "\n".join(lines)


def write_if_changed(path: Path, text: str) -> None:
    """Write ``text`` unless the file holds it already (keeps Sphinx's rebuilds incremental)."""
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


def write_pages(folder: Path) -> list[Path]:
    """Write every id's page and the index into ``folder``; return the pages' paths."""
    folder.mkdir(parents=True, exist_ok=True)
    entries = registered()
    paths = []
    for entry in entries:
        path = folder / f"{entry.env_id}.md"
        write_if_changed(path, page(entry))
        paths.append(path)
    write_if_changed(folder / "index.md", index(entries))
    return paths


if __name__ == "__main__":
    for written in write_pages(DOCS / "envs"):
        print(written)

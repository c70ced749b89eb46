"""Every registered env class documents itself in Gymnasium v5's sections, in order, and its
``## Arguments`` names every argument ``gym.make`` passes on (config fields and keywords)."""

from __future__ import annotations

import dataclasses
import importlib
import inspect

import gymnasium as gym
import pytest

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.envs.glove_grasp import GloveGraspEnv
from ias_gym.envs.glove_grasp_config import GloveGraspConfig
from ias_gym.registration import ENV_SPECS, HARDWARE_ENV_SPECS

#: Gymnasium v5's env docstring sections (e.g. its MuJoCo envs), in their order.
SECTIONS = [
    "## Description",
    "## Action Space",
    "## Observation Space",
    "## Rewards",
    "## Starting State",
    "## Episode End",
    "## Arguments",
    "## Version History",
]
REGISTERED = {**ENV_SPECS, **HARDWARE_ENV_SPECS}


def env_class(env_id: str) -> type:
    module, name = REGISTERED[env_id][0].split(":")
    cls: type = getattr(importlib.import_module(module), name)
    return cls


def own_docstring(cls: type) -> str:
    # cls.__doc__, not inspect.getdoc: a subclass without its own would inherit its base's.
    doc = cls.__dict__.get("__doc__")
    assert doc, f"{cls.__name__} has no docstring of its own"
    return inspect.cleandoc(doc)


def arguments_section(doc: str) -> str:
    return doc.split("## Arguments", 1)[1].split("## Version History", 1)[0]


@pytest.mark.parametrize("env_id", sorted(REGISTERED))
def test_env_docstring_has_the_gymnasium_sections_in_order(env_id: str) -> None:
    doc = own_docstring(env_class(env_id))
    headings = [line for line in doc.splitlines() if line.startswith("## ")]
    assert headings == SECTIONS
    sections = doc.split("\n## ")[1:]
    assert all(s.partition("\n")[2].strip() for s in sections), "an empty section"


@pytest.mark.parametrize("env_id", sorted(REGISTERED))
def test_env_docstring_arguments_name_every_config_field_and_keyword(env_id: str) -> None:
    cls = env_class(env_id)
    arguments = arguments_section(own_docstring(cls))
    names = {
        p.name
        for p in inspect.signature(cls.__init__).parameters.values()
        if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and p.name != "self"
    }
    config = getattr(cls, "config_class", GloveGraspConfig if cls is GloveGraspEnv else None)
    if config is not None:  # the hardware env refers to GloveGraspEnv's for its config
        names |= {f.name for f in dataclasses.fields(config)}
    missing = sorted(n for n in names if f"``{n}``" not in arguments)
    assert not missing, f"{cls.__name__}'s ## Arguments does not name {missing}"


def observation_table(cls: type) -> list[tuple[str, str]] | None:
    """``(name, size)`` rows of the first table in the ``## Observation Space`` of ``cls`` or
    of the first base whose own docstring has one (``As IAS-...``); None: no table."""
    for klass in cls.__mro__:
        doc = klass.__dict__.get("__doc__")
        if not doc or "## Observation Space" not in doc:
            continue
        section = inspect.cleandoc(doc).split("## Observation Space", 1)[1].split("\n## ", 1)[0]
        rows = [
            [cell.strip() for cell in line.strip().strip("|").split("|")]
            for line in section.splitlines()
            if line.strip().startswith("| ``")
        ]
        if rows:
            return [(name.strip("`"), size) for name, size, *_ in rows]
    return None


#: Registered envs whose docstrings list the observation's parts in prose, not as a table.
NO_OBSERVATION_TABLE: set[str] = set()


@pytest.mark.parametrize("env_id", sorted(REGISTERED))
def test_env_docstring_tables_the_observation_layout(env_id: str) -> None:
    """The docstring's table names the parts of ``env.unwrapped.observation_layout`` in
    order, with their sizes (``3k``: 3 per finger of the env's hand)."""
    table = observation_table(env_class(env_id))
    if env_id in NO_OBSERVATION_TABLE:
        assert table is None, f"{env_id} has a table now: test it (drop it from the set)"
        return
    assert table, f"{env_id}'s ## Observation Space has no table of the observation's parts"
    if env_id == "IAS-GloveHardware-v0":  # needs a CAN bus; its layout is the glove world's
        from ias_gym.envs.glove_world import OBSERVATION_PARTS

        parts, fingers = OBSERVATION_PARTS, 0
    else:
        env = gym.make(env_id)
        unwrapped = env.unwrapped
        parts = tuple(
            (name, s.stop - s.start)
            for name, s in unwrapped.observation_layout.items()  # type: ignore[attr-defined]
        )
        fingers = len(getattr(getattr(unwrapped, "hand", None), "fingers", ()))
        env.close()
    sizes = [(name, 3 * fingers if size == "3k" else int(size)) for name, size in table]
    assert sizes == list(parts)

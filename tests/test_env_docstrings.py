"""Every registered env class documents itself in Gymnasium v5's sections, in order, and its
``## Arguments`` names every argument ``gym.make`` passes on (config fields and keywords)."""

from __future__ import annotations

import dataclasses
import importlib
import inspect

import pytest

from ias_gym.envs.glove_grasp import GloveGraspConfig, GloveGraspEnv
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

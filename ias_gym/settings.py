"""Settings the package reads from the environment (the test suite's perturbation mode)."""

from __future__ import annotations

import os

from ias_gym.errors import InputError


def seed_from_environment(name: str) -> int | None:
    """The environment variable ``name`` as a numpy seed, None if it is unset or empty.

    Raises:
        InputError: the variable is set but is not an integer >= 0.
    """
    value = os.environ.get(name, "").strip()
    if not value:
        return None
    try:
        seed = int(value)
    except ValueError:
        seed = -1
    if seed < 0:
        raise InputError(f"{name} must be an integer >= 0, not {value!r}")
    return seed

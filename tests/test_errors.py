"""Every exception class of the package lives in ``ias_gym.errors``, under one base."""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import ias_gym
from ias_gym import errors


def test_every_exception_class_is_in_errors_under_one_base() -> None:
    elsewhere = []
    for info in pkgutil.walk_packages(ias_gym.__path__, "ias_gym."):
        if info.name.endswith("__main__"):  # runs the CLI
            continue
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            if inspect.isclass(obj) and issubclass(obj, BaseException):
                if obj.__module__.startswith("ias_gym") and obj.__module__ != errors.__name__:
                    elsewhere.append(f"{obj.__module__}.{name}")
    assert not elsewhere, f"define these in ias_gym/errors.py: {sorted(set(elsewhere))}"
    own = [c for c in vars(errors).values() if inspect.isclass(c) and issubclass(c, Exception)]
    assert len(own) > 20 and all(issubclass(c, errors.IasGymError) for c in own)

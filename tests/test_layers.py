"""The package's layers: imports go downward only, the library never imports the command line.

The layer order and the contracts are ``[tool.importlinter]`` in pyproject.toml
(docs/layout.md). These tests run the contracts and check, at run time, the two properties the
layering is for: a library module never holds argparse (the command line is the top
layer, :mod:`ias_gym.cli`), and importing ``ias_gym.baselines`` (where the pure control law
lives) does not load the envs or MuJoCo.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(code: str) -> str:
    """Run ``code`` in a fresh interpreter (a clean ``sys.modules``) at the repository root."""
    result = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    return result.stdout.strip()


def test_import_contracts_are_kept() -> None:
    script = Path(sys.executable).with_name("lint-imports")
    if importlib.util.find_spec("importlinter") is None or not script.exists():
        pytest.skip("import-linter is not installed (the [dev] extra)")
    result = subprocess.run(
        [str(script), "--no-cache", str(ROOT / "pyproject.toml")],
        capture_output=True,
        text=True,
        cwd=ROOT,  # the checked package is the one in this checkout
        check=False,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert "0 broken" in result.stdout


def test_no_library_module_holds_the_command_line() -> None:
    # Import every module outside ias_gym.cli, then look for argparse and ias_gym.cli in them.
    out = _run(
        """
        import argparse, importlib, pkgutil, sys
        import ias_gym

        names = []

        def walk(path, prefix):  # pkgutil.walk_packages would import ias_gym.cli to walk it
            for m in pkgutil.iter_modules(path, prefix):
                if m.name != "ias_gym.cli":
                    names.append(m.name)
                    module = importlib.import_module(m.name)
                    if m.ispkg:
                        walk(module.__path__, m.name + ".")

        walk(ias_gym.__path__, "ias_gym.")
        offenders = sorted(
            name
            for name, module in list(sys.modules.items())
            if name.startswith("ias_gym.")
            and not name.startswith("ias_gym.cli")
            and any(value is argparse for value in vars(module).values())
        )
        print(len(names), "cli" if "ias_gym.cli" in sys.modules else "-", offenders)
        """
    )
    count, cli, offenders = out.split(" ", 2)
    assert int(count) > 40  # the walk did find the package's modules
    assert cli == "-", "a library module imported ias_gym.cli"
    assert offenders == "[]", f"library modules with argparse: {offenders}"


def test_importing_baselines_loads_neither_envs_nor_mujoco() -> None:
    # The package spans two layers: its __init__ must not drag the upper one in.
    out = _run(
        """
        import sys
        import ias_gym.baselines.law
        loaded = sorted(
            m for m in sys.modules
            if m == "mujoco" or m.startswith(("ias_gym.envs", "ias_gym.sim", "torch"))
        )
        print(loaded)
        """
    )
    assert out == "[]"


def _modules() -> list[Path]:
    return sorted((ROOT / "ias_gym").rglob("*.py"))


def test_no_module_is_over_500_lines() -> None:
    """A module a newcomer reads in one sitting: none of the package's is over 500 lines."""
    long = {
        str(p.relative_to(ROOT)): n
        for p in _modules()
        if (n := len(p.read_text().splitlines())) > 500
    }
    assert not long, long


def test_module_names_are_unique() -> None:
    """No two modules share a name (``__init__.py`` aside): a name says which module it is."""
    seen: dict[str, list[str]] = {}
    for p in _modules():
        if p.name != "__init__.py":
            seen.setdefault(p.name, []).append(str(p.relative_to(ROOT)))
    assert not {name: paths for name, paths in seen.items() if len(paths) > 1}

"""train/fit_assistant.py: the stop test is chosen by the sessions it produces."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from tests.train_scripts import load_train_script


@pytest.fixture(scope="module")
def fit() -> ModuleType:
    return load_train_script("fit_assistant")


def _outcomes(unimpaired: list[bool], stopped: list[bool], persons: list[int]) -> np.ndarray:
    rows = [(0, s, p) for s, p in zip(unimpaired, persons, strict=True)]
    rows += [(1, s, p) for s, p in zip(stopped, persons, strict=True)]
    return np.array(rows, dtype=float)


def test_an_unimpaired_loss_outweighs_any_completed_stop(fit: ModuleType) -> None:
    persons = [0, 1, 2, 3]
    never_latches = _outcomes([True] * 4, [False] * 4, persons)
    latches = _outcomes([True, True, True, False], [True] * 4, persons)
    later = _outcomes([True] * 4, [True, True, False, False], persons)
    table = {(0.2, 0.01): never_latches, (0.1, 0.4): latches, (0.2, 0.2): later}
    assert fit.rates(latches[:, :2]) == (0.75, 1.0)
    assert fit.choose(table, np.array(persons), "no-loss") == (0.2, 0.2)
    assert fit.choose(table, np.array(persons), "balanced") == (0.1, 0.4)


def test_the_choice_reads_only_the_given_persons(fit: ModuleType) -> None:
    a = _outcomes([True, True], [True, False], [0, 1])  # person 0: all good
    b = _outcomes([True, True], [False, True], [0, 1])  # person 1: all good
    table = {(0.1, 0.1): a, (0.1, 0.2): b}
    assert fit.choose(table, np.array([0]), "no-loss") == (0.1, 0.1)
    assert fit.choose(table, np.array([1]), "no-loss") == (0.1, 0.2)


def test_a_kind_without_sessions_scores_nothing(fit: ModuleType) -> None:
    only_unimpaired = np.array([(0, 1.0), (0, 1.0)])
    assert fit.rates(only_unimpaired) == (1.0, 0.0)


@pytest.mark.parametrize(
    "args",
    [
        ["--ratios", "0.2,x"],
        ["--ratios", "1.5"],
        ["--windows", "0"],
        ["--persons", "2"],
        ["--db", "no-such-library.db"],
    ],
)
def test_bad_grids_are_refused_before_any_session(
    fit: ModuleType, args: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "params.json"
    assert fit.main([*args, "--out", str(out)]) == 2
    assert capsys.readouterr().err.strip()
    assert not out.exists()


def test_an_existing_parameter_file_is_kept(fit: ModuleType, tmp_path: Path) -> None:
    out = tmp_path / "params.json"
    out.write_text("{}")
    assert fit.main(["--persons", "5", "--out", str(out)]) == 2
    assert out.read_text() == "{}"

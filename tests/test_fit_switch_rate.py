"""train/fit_switch_rate.py: the switches it draws, the rate and temper it chooses, what it
refuses."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import pytest

from ias_gym.glove.skills import SKILLS
from tests.train_scripts import load_train_script


@pytest.fixture(scope="module")
def fit() -> ModuleType:
    return load_train_script("fit_switch_rate")


def test_switches_are_distinct_pairs_drawn_reproducibly_per_person(fit: ModuleType) -> None:
    drawn = fit.drawn_switches("somebody", 6)
    assert drawn == fit.drawn_switches("somebody", 6)
    assert drawn != fit.drawn_switches("somebody-else", 6)
    assert len({(a, b) for a, b, _ in drawn}) == 6
    lo, hi = fit.SWITCH_TIMES
    for a, b, t in drawn:
        assert a in SKILLS and b in SKILLS and a != b
        assert lo <= t <= hi


def test_the_choice_counts_every_kind_alike_on_the_given_persons(fit: ModuleType) -> None:
    # rows (kind, person, right); points (temper, rate)
    sticky = [("plain", "p", True), ("switch", "p", False), ("left out", "q", True)]
    loose = [("plain", "p", True), ("switch", "p", True), ("left out", "q", False)]
    outcomes = {(0.1, 1e-20): sticky, (0.1, 1e-9): loose}
    assert fit.choose(outcomes, {"p", "q"}) == (0.1, 1e-20)  # a tie: the lower rate
    assert fit.choose(outcomes, {"p"}) == (0.1, 1e-9)
    assert fit.choose(outcomes, {"q"}) == (0.1, 1e-20)
    # a tie between tempers: the lower (the posterior least sure)
    assert fit.choose({(0.1, 1e-20): sticky, (0.05, 1e-10): sticky}, {"p"}) == (0.05, 1e-10)


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--tempers", "0,0.1"], "--tempers"),
        (["--tempers", "0.1,1.5"], "--tempers"),
        (["--tempers", "a,b"], "--tempers"),
        (["--costs", "950,-1"], "--costs"),
        (["--costs", "nan"], "--costs"),
        (["--persons", "3", "--folds", "4"], "--persons"),
        (["--switches", "0"], "--switches"),
    ],
)
def test_bad_arguments_are_refused_before_any_session(
    fit: ModuleType,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    extra: list[str],
    needle: str,
) -> None:
    db = tmp_path / "lib.db"
    db.write_text("")
    report = tmp_path / "r.json"
    args = ["--db", str(db), "--seed", "1", "--report", str(report), *extra]
    assert fit.main(args) == 2
    assert needle in capsys.readouterr().err
    assert not report.exists()


def test_a_missing_library_and_an_existing_report_are_refused(
    fit: ModuleType, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    report = tmp_path / "r.json"
    assert fit.main(["--db", str(tmp_path / "no.db"), "--seed", "1", "--report", str(report)]) == 2
    assert "--db" in capsys.readouterr().err
    db = tmp_path / "lib.db"
    db.write_text("")
    report.write_text("{}")
    assert fit.main(["--db", str(db), "--seed", "1", "--report", str(report)]) == 2
    assert "overwrite" in capsys.readouterr().err
    assert report.read_text() == "{}"

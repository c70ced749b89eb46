"""train/assist_table.py and train/assist_residual.py: persons drawn from the population,
bad input refused before any work, the rates' intervals."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ias_gym.assist.assistance_evaluation import ImpairmentScore
from tests.train_scripts import load_train_script


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--persons", "0", "--population-seed", "1", "--set", "development"], "population size"),
        (["--persons", "3", "--population-seed", "-1", "--set", "development"], "seed"),
    ],
)
def test_the_table_refuses_a_bad_population_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], expected: str
) -> None:
    table = load_train_script("assist_table")
    out = tmp_path / "table"
    assert table.main([*args, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert expected in err and len(err.splitlines()) == 1
    assert not list(tmp_path.iterdir())


def test_the_table_refuses_to_replace_its_outputs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    table = load_train_script("assist_table")
    (tmp_path / "table.json").write_text("{}")
    args = ["--persons", "2", "--population-seed", "1", "--set", "development"]
    assert table.main([*args, "--out", str(tmp_path / "table")]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert (tmp_path / "table.json").read_text() == "{}"


def test_the_residual_refuses_a_bad_population_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    residual = load_train_script("assist_residual")
    out = tmp_path / "residual.zip"
    assert residual.main(["--persons", "0", "--out", str(out)]) == 2
    assert "population size" in capsys.readouterr().err
    assert not out.exists()


def test_a_score_gives_its_successes_with_intervals() -> None:
    score = ImpairmentScore(15, 30, 0.1, sessions=30, excluded=2)
    row = score.to_json()
    assert row["unassisted"]["successes"] == 15 and row["unassisted"]["trials"] == 30
    assert row["assisted"]["successes"] == 30
    low, high = row["unassisted"]["ci95_low"], row["unassisted"]["ci95_high"]
    assert low < 0.5 < high and high - low > 0.3  # 30 sessions: a wide interval
    assert row["assisted"]["ci95_high"] == 1.0 and row["assisted"]["ci95_low"] < 0.9
    assert row["success_unassisted"] == 0.5 and row["sessions"] == 30
    empty = ImpairmentScore(0, 0, float("nan"), 0).to_json()
    assert empty["assisted"] is None and empty["success_assisted"] is None


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--db", "missing.db"], "--db missing.db does not exist"),
        (["--residual", "missing.zip"], "--residual missing.zip does not exist"),
        (["--residual", "NOT_A_MODEL"], "not an SB3 model"),
    ],
)
def test_the_population_table_refuses_missing_inputs_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], expected: str
) -> None:
    table = load_train_script("assist_population")
    (tmp_path / "not_a_model.zip").write_text("no zip")
    args = [str(tmp_path / "not_a_model.zip") if a == "NOT_A_MODEL" else a for a in args]
    out = tmp_path / "table.json"
    argv = ["--seed", "1", "--set", "development", "--out", str(out), *args]
    assert table.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert expected in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_an_ablation_arm_runs_the_assistant_without_its_part() -> None:
    table = load_train_script("assist_population")
    assert table.arms_of(None, ("pads",)) == (*table.ARMS, "without_pads")
    job = table.PersonJob(("none",), ("tilt_left",), None, 0, without=("pads",))
    records, unjudged = job("p1")
    assert unjudged == []  # p1's tilt has its unimpaired reference
    assert sorted(r["arm"] for r in records) == sorted(table.arms_of(None, ("pads",)))
    # every judged session's record: who, what was drawn, which arm, how it ended
    for record in records:
        assert record["person"] == "p1" and record["skill"] == "tilt_left"
        assert record["spec"] == "none" and record["drawn"] == "none"
        assert isinstance(record["success"], bool)
        assert {"pad_off_from_s", "position_error_mm", "lift_height_error_mm"} <= set(record)


def test_the_population_table_refuses_to_replace_a_sessions_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    table = load_train_script("assist_population")
    sessions, out = tmp_path / "sessions.json", tmp_path / "table.json"
    sessions.write_text("[]")
    argv = ["--seed", "1", "--set", "development", "--out", str(out)]
    assert table.main([*argv, "--sessions", str(sessions)]) == 2
    err = capsys.readouterr().err.strip()
    assert "--overwrite" in err and len(err.splitlines()) == 1
    assert table.main([*argv, "--sessions", str(out)]) == 2
    assert "other than --out" in capsys.readouterr().err
    assert sessions.read_text() == "[]" and not out.exists()


def _session(person: str, arm: str, success: bool, drawn: str = "lag:s=0.2") -> dict[str, object]:
    return {
        "person": person,
        "spec": "sampled",
        "drawn": drawn,
        "skill": "tilt_left",
        "arm": arm,
        "success": success,
        "position_error_mm": 3.5,
    }


def test_the_sessions_of_two_arms_are_set_side_by_side(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sessions = load_train_script("assist_sessions")
    records = [
        _session("a", "assisted", True),
        _session("a", "without_tremor", False),
        _session("b", "assisted", False),
        _session("b", "without_tremor", True),
        _session("c", "assisted", True, "tremor:hz=5"),
        _session("c", "without_tremor", True, "tremor:hz=5"),
        _session("d", "assisted", True),  # judged by one arm only: left out
        _session("e", "assisted", False, "tremor:hz=5+weak_grip:rad=0.1"),
        _session("e", "without_tremor", False, "tremor:hz=5+weak_grip:rad=0.1"),
    ]
    result = sessions.compare(records, "assisted", "without_tremor")
    assert result["counts"]["sampled"] == {
        "lag": {"sessions": 2, "assisted": 1, "without_tremor": 1},
        "tremor": {"sessions": 1, "assisted": 1, "without_tremor": 1},
        "tremor+weak_grip": {"sessions": 1, "assisted": 0, "without_tremor": 0},
    }
    assert [(r["person"], r["arm"]) for r in result["won"]] == [("a", "without_tremor")]
    assert [(r["person"], r["arm"]) for r in result["lost"]] == [("b", "assisted")]
    path = tmp_path / "sessions.json"
    path.write_text(json.dumps(records))
    assert sessions.main([str(path), "--against", "without_tremor"]) == 0
    assert "3.50" in capsys.readouterr().out
    # bad input: one line, exit 2
    for argv in ([str(tmp_path / "missing.json")], [str(path), "--arm", "residual"]):
        assert sessions.main(argv) == 2
        assert len(capsys.readouterr().err.strip().splitlines()) == 1
    path.write_text('{"not": "a list"}')
    assert sessions.main([str(path)]) == 2
    assert "no list of session records" in capsys.readouterr().err

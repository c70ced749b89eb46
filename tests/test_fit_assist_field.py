"""train/fit_assist_field.py: one field of the assistant, chosen by the sessions it produces
against the impairment it is for; the other fields and their records are kept."""

from __future__ import annotations

import json
from pathlib import Path
from types import ModuleType

import pytest

from ias_gym.assist.motion_completion import AssistParams
from ias_gym.glove.impairment_spec import parse_impairment
from tests.train_scripts import load_train_script


@pytest.fixture(scope="module")
def fit() -> ModuleType:
    return load_train_script("fit_assist_field")


def test_every_field_is_one_of_the_assistants_and_draws_valid_specs(fit: ModuleType) -> None:
    fields = set(AssistParams.__dataclass_fields__)
    for name, field in fit.FIELDS.items():
        assert name in fields
        spec = field.draw("somebody", "tilt_left")
        assert spec.split(":")[0] in (field.families or (field.family,))
        parse_impairment(spec)  # within the family's ranges
        assert spec == field.draw("somebody", "tilt_left")  # reproducible per person and skill


def test_a_balanced_choice_weighs_both_kinds_and_reads_only_the_given_persons(
    fit: ModuleType,
) -> None:
    # rows (kind, success, person): kind 0 unimpaired, 1 impaired
    safe = [(0, True, 0), (0, True, 1), (1, False, 0), (1, False, 1)]
    bold = [(0, True, 0), (0, False, 1), (1, True, 0), (1, True, 1)]
    outcomes = {1.0: safe, 2.0: bold}
    assert fit.choose(outcomes, {0, 1}, "no-loss") == 1.0
    assert fit.choose(outcomes, {0, 1}, "balanced") == 2.0
    assert fit.choose(outcomes, {0}, "no-loss") == 2.0  # person 0 loses nothing either way


def test_a_fit_replaces_only_its_own_record(fit: ModuleType) -> None:
    record = "16 persons, seed 1; tremor_window_s: 8 persons, seed 2"
    assert fit.fitted_on(record, "sight_gain", "4 persons, seed 3") == (
        "16 persons, seed 1; tremor_window_s: 8 persons, seed 2; sight_gain: 4 persons, seed 3"
    )
    assert fit.fitted_on(record, "tremor_window_s", "4 persons, seed 3") == (
        "16 persons, seed 1; tremor_window_s: 4 persons, seed 3"
    )


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--field", "sight_gain", "--grid", "1,x"], "--grid 1,x must be"),
        (["--field", "sight_gain", "--grid", "0"], "--grid 0 must be"),
        (["--field", "sight_gain", "--persons", "2"], "--persons 2 cannot fill 4 folds"),
        (["--field", "pad_close_rate", "--db", "no-such.db"], "--db no-such.db does not exist"),
        (
            ["--field", "tremor_trend_degree", "--grid", "1,2.5"],
            "--grid 2.5: tremor_trend_degree takes whole numbers",
        ),
    ],
)
def test_bad_input_is_refused_before_any_session(
    fit: ModuleType,
    args: list[str],
    expected: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    out = tmp_path / "params.json"
    AssistParams().save(out)
    before = out.read_text()
    report = tmp_path / "report.json"
    code = fit.main(
        [*args, "--seed", "1", "--out", str(out), "--report", str(report), "--overwrite"]
    )
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert expected in err and len(err.splitlines()) == 1
    assert out.read_text() == before and not report.exists()


def test_an_integer_field_is_stored_as_one_the_parameters_load(
    fit: ModuleType, tmp_path: Path
) -> None:
    value = fit.field_value("tremor_trend_degree", 3.0)
    assert value == 3 and isinstance(value, int)
    assert fit.field_value("sight_gain", 3.0) == 3.0
    path = tmp_path / "params.json"
    AssistParams(tremor_trend_degree=value).save(path)
    assert AssistParams.load(path).tremor_trend_degree == 3


def test_the_shipped_catch_up_pace_catches_up() -> None:
    """A pace of 1 or less never returns to the fitted timeline."""
    assert AssistParams.load().catch_up_pace > 1.0


@pytest.mark.parametrize(
    ("field", "report_name"),
    [
        ("catch_up_pace", "catch_up_fit.json"),
        ("stop_hold_s", "stop_hold_fit.json"),
        ("min_remaining_rad", "min_remaining_fit.json"),
        ("min_model_speed", "min_speed_fit.json"),
        ("onset_rad", "onset_fit.json"),
    ],
)
def test_the_shipped_completion_fields_are_the_fitted_ones(field: str, report_name: str) -> None:
    """Each of the completion's fitted fields is the value its fit chose (its report in
    docs/), chosen by the unimpaired success first: no grid value loses fewer unimpaired
    sessions."""
    report = json.loads((Path(__file__).parents[1] / "docs" / report_name).read_text())
    assert report["objective"] == "no-loss"
    assert getattr(AssistParams.load(), field) == report[field]
    unimpaired = {v: row["unimpaired"]["successes"] for v, row in report["grid"].items()}
    assert unimpaired[str(report[field])] == max(unimpaired.values())
    assert field in AssistParams.load().fitted_on

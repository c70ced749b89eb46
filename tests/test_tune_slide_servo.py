"""``train/tune_slide_servo.py``: the sweep that chose the expert's slide servo."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.train_scripts import load_train_script


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["--classes", "weather"], "unknown disturbance class"),
        (["--kp", "stiff"], "take numbers"),
        (["--kv", "-1"], "must be >= 0"),
        (["--out-json", "runs.txt"], "--out-json"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    args: list[str], match: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert load_train_script("tune_slide_servo").main(args) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and match in lines[0], lines


def test_a_stiffer_servo_ends_a_finger_nearer_its_target_where_friction_is_wrong(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """At mu x 0.7 the servo's spring alone closes the friction mismatch, so the error falls
    with the stiffness (about 1.9 mm at 30 N/m, 0.8 mm at 90 N/m): the sweep picks 90."""
    out = tmp_path / "sweep.json"
    args = ["--kp", "30,90", "--kv", "2", "--classes", "friction_x0.7", "--seeds", "881000"]
    code = load_train_script("tune_slide_servo").main(
        [*args, "--workers", "1", "--out-json", str(out)]
    )
    assert code == 0
    assert "chosen: kp_slide 90 N/m" in capsys.readouterr().out
    runs = {r["kp_slide_N_per_m"]: r for r in json.loads(out.read_text())["runs"]}
    assert runs[90.0]["final_slide_error_mm"] < runs[30.0]["final_slide_error_mm"] - 0.5

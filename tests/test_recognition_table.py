"""train/recognition_table.py: what it refuses before any recording."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import pytest

from tests.train_scripts import load_train_script


def _script() -> ModuleType:
    return load_train_script("recognition_table")


def test_more_demonstrations_than_library_persons_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["--population-seed", "1", "--set", "development", "--library-persons", "2"]
    code = _script().main([*args, "--demos", "3", "--out", str(tmp_path / "rec")])
    assert code == 2
    assert "--demos" in capsys.readouterr().err
    assert not (tmp_path / "rec").exists(), "nothing is written"


def test_existing_outputs_are_kept_without_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "rec"
    out.mkdir()
    (out / "recognition.json").write_text("{}")
    args = ["--population-seed", "1", "--set", "held-out", "--out", str(out)]
    assert _script().main([*args, "--plot", str(out / "r.png")]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert (out / "recognition.json").read_text() == "{}"
    assert not list(out.glob("*.db")), "no session was recorded"


def test_the_set_must_be_said() -> None:
    with pytest.raises(SystemExit) as exc:
        _script().main(["--population-seed", "1"])
    assert exc.value.code == 2

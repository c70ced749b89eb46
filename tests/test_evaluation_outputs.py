"""Output paths are checked before any work, written atomically and never replaced silently.

``evaluate --video`` and ``figure --out`` used to find out that they cannot write only after
rendering an episode / computing the figure, and replaced existing files without asking.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import ias_gym.figures.wrench_intensities as wrench
from ias_gym.cli import main
from ias_gym.errors import InputError
from ias_gym.evaluation import evaluate_spec, write_video
from ias_gym.outputs import OutputExistsError, check_output_files

os.environ.setdefault("MUJOCO_GL", "egl")

SHORT = json.dumps({"duration": 0.05, "settle_time": 0.0})  # [s]: 5 steps, judged from 0 s
EVALUATE = ["evaluate", "--env", "IAS-PenRotate-v0", "--policy", "random", "--episodes", "1"]
linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc")


@pytest.fixture
def no_work(monkeypatch: pytest.MonkeyPatch) -> None:
    """Building an env or computing the figure fails the test: the checks come first."""

    def fail(*args: object, **kwargs: object) -> None:
        raise AssertionError("work started before the output path was checked")

    monkeypatch.setattr(gym, "make", fail)
    monkeypatch.setattr(wrench, "wrench_intensity_table", fail)


def _error_line(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@linux_only
@pytest.mark.usefixtures("no_work")
def test_unwritable_video_path_fails_before_the_env_is_built(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(InputError, match="cannot write into /proc"):
        evaluate_spec("IAS-PenRotate-v0", "random", episodes=1, video=Path("/proc/x.mp4"))
    line = _error_line([*EVALUATE, "--video", "/proc/x.mp4"], capsys)
    assert "video /proc/x.mp4" in line
    missing = tmp_path / "no" / "such" / "dir" / "x.mp4"
    line = _error_line([*EVALUATE, "--video", str(missing)], capsys)
    assert "does not exist" in line and not missing.parent.exists()
    line = _error_line([*EVALUATE, "--video", str(tmp_path / "x.gif")], capsys)
    assert "must end with .mp4" in line
    line = _error_line([*EVALUATE, "--video", str(tmp_path)], capsys)
    assert "is a directory" in line


def test_existing_video_is_refused_then_replaced_with_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    video = tmp_path / "episode.mp4"
    video.write_bytes(b"keep me")
    argv = [*EVALUATE, "--env-kwargs", SHORT, "--video", str(video)]
    with monkeypatch.context() as patch:  # refused before any episode runs
        patch.setattr(gym, "make", lambda *a, **k: pytest.fail("env built"))
        line = _error_line(argv, capsys)
    assert "already exists" in line and "--overwrite" in line
    assert video.read_bytes() == b"keep me"

    assert main([*argv, "--overwrite", "--json"]) == 0
    import imageio.v3 as iio

    frames = iio.imread(video)
    assert frames.ndim == 4 and frames.shape[0] >= 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["episode.mp4"]  # no temp file left


def test_video_is_written_atomically_and_never_replaces_a_newcomer(tmp_path: Path) -> None:
    frames = [np.zeros((16, 16, 3), np.uint8) + i for i in range(3)]
    video = tmp_path / "v.mp4"
    # A failing writer leaves neither the video nor a temporary file.
    with pytest.raises(Exception):  # noqa: B017  (whatever imageio raises for bad frames)
        write_video(video, [np.zeros((16, 16, 7), np.float32)], fps=10)
    assert list(tmp_path.iterdir()) == []
    # A file that appeared while the episode ran is not replaced without overwrite.
    video.write_bytes(b"appeared meanwhile")
    with pytest.raises(OutputExistsError):
        write_video(video, frames, fps=10)
    assert video.read_bytes() == b"appeared meanwhile"
    assert [p.name for p in tmp_path.iterdir()] == ["v.mp4"]
    write_video(video, frames, fps=10, overwrite=True)
    assert video.stat().st_size > 100 and len(list(tmp_path.iterdir())) == 1


@linux_only
@pytest.mark.usefixtures("no_work")
def test_unwritable_figure_directory_fails_before_the_computation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    line = _error_line(["figure", "wrench-intensities", "--out", "/proc/figures"], capsys)
    assert "cannot create the output directory /proc/figures" in line
    line = _error_line(["figure", "control-error", "--out", "/proc/figures"], capsys)
    assert "/proc/figures" in line
    a_file = tmp_path / "file"
    a_file.write_text("")
    line = _error_line(["figure", "wrench-intensities", "--out", str(a_file)], capsys)
    assert "is a file" in line


def test_figure_creates_its_directory_and_refuses_to_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "new" / "figures"
    argv = ["figure", "wrench-intensities", "--out", str(out), "--cone", "box"]
    assert main(argv) == 0
    csv = out / "wrench_intensities.csv"
    png = out / "wrench_intensities.png"
    before = {p: p.stat().st_mtime_ns for p in (csv, png)}
    capsys.readouterr()
    line = _error_line(argv, capsys)
    assert str(csv) in line and str(png) in line and "--overwrite" in line
    assert {p: p.stat().st_mtime_ns for p in (csv, png)} == before
    csv.write_text("stale")
    assert main([*argv, "--overwrite"]) == 0
    assert csv.read_text().startswith("t,c1,")
    assert sorted(p.name for p in out.iterdir()) == [csv.name, png.name]


def test_a_commands_output_files_are_checked_together(tmp_path: Path) -> None:
    """Each output is checked as one file is; one not asked for stays None; two options
    naming one file (even by another spelling) are refused, before anything is written."""
    out, report = tmp_path / "out.json", tmp_path / "report.json"
    checked = check_output_files({"--out": out, "--report": None})
    assert checked == {"--out": out, "--report": None}
    with pytest.raises(InputError, match="--report: give a file other than --out's"):
        check_output_files({"--out": out, "--report": tmp_path / "." / "out.json"})
    report.write_text("{}")
    with pytest.raises(OutputExistsError):
        check_output_files({"--out": out, "--report": report})
    assert check_output_files({"--report": report}, overwrite=True)["--report"] == report
    assert report.read_text() == "{}" and not out.exists()

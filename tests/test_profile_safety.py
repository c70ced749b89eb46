"""Calibration profiles: absurd numbers refused on load, `ias-gym calibrate` never replaces a
profile silently and refuses out-of-range numbers before it trains."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ias_gym.cli.glove_commands import add_glove_commands
from ias_gym.errors import InputError
from ias_gym.glove import (
    PersonParams,
    Profile,
    ProfileError,
    evaluate,
    fit_linear,
    load_profile,
    record_session,
    save_profile,
)

GLOVE = "test-glove"


@pytest.fixture(scope="module")
def profile_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A linear-calibration profile of p2 (numpy only, fast)."""
    train, held = record_session(PersonParams.sample("p2"), 600, seed=0).split()
    calibration = fit_linear(train)
    profile = Profile("p2", GLOVE, calibration, evaluate(calibration, held))
    return save_profile(profile, tmp_path_factory.mktemp("profile") / "profile_p2.json")


def _edited(path: Path, tmp_path: Path, where: tuple[Any, ...], value: Any) -> Path:
    """A copy of the profile with one number replaced (written as JSON text, so 1e309
    stays the literal the file would hold)."""
    data = json.loads(path.read_text())
    node = data
    for key in where[:-1]:
        node = node[key]
    node[where[-1]] = "@@"
    out = tmp_path / "edited.json"
    out.write_text(json.dumps(data).replace('"@@"', value))
    return out


#: (where in the JSON, the number written there, what the error must say)
ABSURD = {
    # the field case: a weight of 1e308 loaded silently and drove MuJoCo into NaN ctrl
    "weight-1e308": (
        ("groups", 1, "layers", 0, "weight", 0, 0),
        "1e308",
        r"groups\[1\]\.layers\[0\]\.weight holds 1e\+308",
    ),
    "weight-2.5e6": (
        ("groups", 0, "layers", 0, "weight", 1, 2),
        "-2.5e6",
        r"groups\[0\]\.layers\[0\]\.weight holds -2\.5e\+06",
    ),
    "bias-1e7": (
        ("groups", 2, "layers", 0, "bias", 0),
        "1e7",
        r"groups\[2\]\.layers\[0\]\.bias holds 1e\+07",
    ),
    "mean-1e300": (("groups", 3, "y_mean", 1), "-1e300", r"groups\[3\]\.y_mean holds -1e\+300"),
    "scale-1e-300": (
        ("groups", 1, "x_scale", 0),
        "1e-300",
        r"groups\[1\]\.x_scale holds 1e-300, below 1e-09",
    ),
}


@pytest.mark.parametrize("case", list(ABSURD))
def test_absurd_numbers_are_refused_naming_the_file_and_the_array(
    profile_file: Path, tmp_path: Path, case: str
) -> None:
    where, value, expected = ABSURD[case]
    path = _edited(profile_file, tmp_path, where, value)
    with pytest.raises(ProfileError, match=expected) as err:
        load_profile(path, glove_id=GLOVE)
    assert str(path) in str(err.value)


def test_largest_accepted_numbers_still_load(profile_file: Path, tmp_path: Path) -> None:
    """The bound is not a tripwire for trained profiles: 1e6 itself loads, and a trained
    profile's numbers are far below it."""
    data = json.loads(profile_file.read_text())
    largest = max(
        abs(v)
        for g in data["groups"]
        for layer in g["layers"]
        for v in np.ravel(layer["weight"]).tolist() + layer["bias"]
    )
    assert largest < 1e3
    path = _edited(profile_file, tmp_path, ("groups", 0, "layers", 0, "bias", 0), "1e6")
    assert load_profile(path).calibration.group("wrist").layers[0][1][0] == 1e6


@pytest.mark.parametrize("key", ["person_id", "glove_id"])
@pytest.mark.parametrize("hostile", ["../x", "/abs/dir", "", "a/b", "..", "x" * 65])
def test_profile_ids_are_checked_on_load_and_save(
    profile_file: Path, tmp_path: Path, key: str, hostile: str
) -> None:
    data = json.loads(profile_file.read_text())
    data[key] = hostile
    path = tmp_path / "hostile.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ProfileError, match=f"{key} .* not a valid id|{key} .* characters long"):
        load_profile(path)
    profile = load_profile(profile_file)
    ids = {"person_id": profile.person_id, "glove_id": profile.glove_id, key: hostile}
    with pytest.raises(InputError, match=key):
        Profile(ids["person_id"], ids["glove_id"], profile.calibration, profile.held_out)


# ---------------------------------------------------------------------------- the command
def _run(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="ias-gym")
    add_glove_commands(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["calibrate", *argv])
    code: int = args.run(args)
    return code


@pytest.mark.parametrize(
    ("extra", "option"),
    [
        # wrote an untrained profile (15.8 deg, 4x the linear error) before
        pytest.param(["--max-iter", "0"], "--max-iter", id="max-iter-0"),
        pytest.param(["--max-iter", "-5"], "--max-iter", id="max-iter-negative"),
        pytest.param(["--max-iter", "100001"], "--max-iter", id="max-iter-huge"),
        pytest.param(["--readings", "99"], "--readings", id="readings-99"),
        pytest.param(["--readings", "1000001"], "--readings", id="readings-huge"),
        pytest.param(["--seed", "-1"], "--seed", id="seed-negative"),
        pytest.param(["--glove-id", "../g"], "--glove-id", id="glove-id-parent"),
        pytest.param(["--person", "/tmp/abs"], "--person", id="person-absolute"),
    ],
)
def test_calibrate_refuses_bad_numbers_and_ids_before_any_work(
    tmp_path: Path, extra: list[str], option: str
) -> None:
    out = tmp_path / "out"
    argv = ["--person", "p1", "--out", str(out), "--readings", "600", "--max-iter", "20"]
    with pytest.raises(InputError, match=option):
        _run([*argv, *extra])
    assert not out.exists()  # checked before training and before any file


def test_calibrate_refuses_an_out_that_is_a_file(tmp_path: Path) -> None:
    out = tmp_path / "file"
    out.write_text("x")
    with pytest.raises(InputError, match="is a file"):
        _run(["--person", "p1", "--out", str(out), "--max-iter", "1"])


def test_calibrate_never_replaces_a_profile_silently(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Exists -> refused without --overwrite; with it a better profile is kept unless
    --force; a worse one is replaced. Before, every run replaced the profile and figure."""
    pytest.importorskip("torch")
    base = ["--person", "p1", "--out", str(tmp_path), "--readings", "600"]
    profile, figure = tmp_path / "profile_p1.json", tmp_path / "calibration_p1.png"
    assert _run([*base, "--max-iter", "80"]) == 0
    good = profile.read_bytes()
    good_figure = figure.read_bytes()
    good_error = load_profile(profile).held_out.rms_deg
    capsys.readouterr()

    with pytest.raises(InputError, match=r"profile_p1\.json.*exist.*--overwrite"):
        _run([*base, "--max-iter", "80"])
    # one training iteration: a worse calibration than the one on disk
    with pytest.raises(InputError, match=r"kept .*profile_p1\.json.*better.*--force"):
        _run([*base, "--max-iter", "1", "--overwrite"])
    assert profile.read_bytes() == good and figure.read_bytes() == good_figure

    assert _run([*base, "--max-iter", "1", "--force"]) == 0
    worse_error = load_profile(profile).held_out.rms_deg
    assert worse_error > good_error
    assert "replaced a profile with held-out joint RMS" in capsys.readouterr().out

    assert _run([*base, "--max-iter", "80", "--overwrite"]) == 0  # better: replaced
    assert load_profile(profile).held_out.rms_deg == pytest.approx(good_error)
    assert sorted(p.name for p in tmp_path.iterdir()) == [figure.name, profile.name]


def test_calibrate_overwrite_replaces_an_unreadable_profile(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("torch")
    profile = tmp_path / "profile_p1.json"
    profile.write_text("{truncated")
    argv = ["--person", "p1", "--out", str(tmp_path), "--readings", "600", "--max-iter", "20"]
    with pytest.raises(InputError, match="exist"):
        _run(argv)
    assert profile.read_text() == "{truncated"
    assert _run([*argv, "--overwrite"]) == 0
    assert "not a usable profile" in capsys.readouterr().err
    assert load_profile(profile).person_id == "p1"


def test_calibrate_help_states_defaults_and_the_overwrite_rule(
    capsys: pytest.CaptureFixture[str],
) -> None:
    with pytest.raises(SystemExit):
        _run(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    for default in ("(default: 0)", "(default: 2000)", "(default: 1500)", "(default: sim-glove-0)"):
        assert default in text
    assert "keep a profile whose held-out joint RMS error is lower" in text

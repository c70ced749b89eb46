"""The sensor glove: sensor model, calibration (eq. 1, Fig. 7), profiles, devices, CLI."""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ias_gym.cli.glove_commands import add_glove_commands
from ias_gym.errors import InputError
from ias_gym.glove import (
    ACTUATED_JOINTS,
    JOINT_NAMES,
    JOINT_RANGES,
    LINEAR_GROUPS,
    NOISE_STD,
    SENSOR_NAMES,
    Calibration,
    CalibrationSession,
    GloveDevice,
    PersonParams,
    Profile,
    ProfileError,
    ReachPinchLift,
    SimulatedGlove,
    evaluate,
    fingertip_gap,
    fit_linear,
    load_profile,
    record_session,
    save_profile,
    sensor_readings,
)
from ias_gym.glove.hand import joint_index, sensor_index
from ias_gym.glove.profile import SCHEMA_VERSION
from ias_gym.glove.sensor_model import FREE_MIN_GAP, PINCH_FORCE_RANGE, pinch_force

#: Short training budget for tests (the default is 1500 L-BFGS iterations).
TEST_ITER = 300
GLOVE = "test-glove"


def train_calibration(*args: Any, **kwargs: Any) -> tuple[Calibration, Any]:
    """The torch trainer (skips the test when torch, the [glove] extra, is missing)."""
    pytest.importorskip("torch")
    from ias_gym.glove.training import train_calibration as train

    return train(*args, **kwargs)


@pytest.fixture(scope="module")
def p2_session() -> tuple[CalibrationSession, CalibrationSession]:
    return record_session(PersonParams.sample("p2"), 1500, seed=0).split()


@pytest.fixture(scope="module")
def p2_ann(p2_session: tuple[CalibrationSession, CalibrationSession]) -> Calibration:
    calibration, _ = train_calibration(p2_session[0], max_iter=TEST_ITER)
    return calibration


@pytest.fixture(scope="module")
def profile_file(
    tmp_path_factory: pytest.TempPathFactory,
    p2_session: tuple[CalibrationSession, CalibrationSession],
    p2_ann: Calibration,
) -> Path:
    metrics = evaluate(p2_ann, p2_session[1])
    profile = Profile("p2", GLOVE, p2_ann, metrics, training={"seed": 0})
    return save_profile(profile, tmp_path_factory.mktemp("profile") / "profile_p2.json")


# --- names, persons, sensor model -------------------------------------------------------


def test_names_ranges_and_lookup_errors() -> None:
    assert len(JOINT_NAMES) == len(SENSOR_NAMES) == 10
    assert JOINT_RANGES["index_mcp"] == (0.0, 1.5) and JOINT_RANGES["index_dip"] == (0.0, 1.2)
    assert all(lo < hi for lo, hi in JOINT_RANGES.values())
    with pytest.raises(KeyError, match="index_pip"):
        joint_index("index_pp")
    with pytest.raises(KeyError, match="thumb_web"):
        sensor_index("web")


def test_person_params_are_reproducible_and_plausible() -> None:
    a, b = PersonParams.sample("p1"), PersonParams.sample("p1")
    assert a == b
    assert PersonParams.sample("p1", seed=1) != a and PersonParams.sample("p2") != a
    for pid in ("p1", "p2", "p3", "p4", "p5", "somebody"):
        p = PersonParams.sample(pid)
        assert 0.85 <= p.hand_scale <= 1.15
        assert 0.035 < p.index_lengths[0] < 0.056 and 0.6 <= p.dip_coupling <= 0.75


def test_sensor_model_is_person_dependent_and_deterministic() -> None:
    rng = np.random.default_rng(0)
    p1, p2 = PersonParams.sample("p1"), PersonParams.sample("p2")
    theta = record_session(p1, 200, seed=3).theta
    # Same Θ, two persons: the noise-free readings differ far beyond the noise.
    diff = np.abs(sensor_readings(theta, p1) - sensor_readings(theta, p2))
    assert np.median(diff) > 5 * NOISE_STD
    linkage = [sensor_index("index_psi1"), sensor_index("index_psi2")]
    assert np.median(diff[:, linkage]) > 5 * NOISE_STD
    # Even with gains and offsets equal, the hand geometry alone changes ψ1, ψ2.
    same_mount = dataclasses.replace(p2, gains=p1.gains, offsets=p1.offsets)
    geo = np.abs(sensor_readings(theta, p1) - sensor_readings(theta, same_mount))[:, linkage]
    assert np.median(geo) > 5 * NOISE_STD
    # Deterministic for a seed; the noise has the documented size.
    n1 = sensor_readings(theta, p1, np.random.default_rng(7))
    np.testing.assert_array_equal(n1, sensor_readings(theta, p1, np.random.default_rng(7)))
    assert not np.array_equal(n1, sensor_readings(theta, p1, rng))
    noise = n1 - sensor_readings(theta, p1)
    assert noise.std() == pytest.approx(NOISE_STD, rel=0.1)
    s1, s2 = record_session(p1, 300, seed=5), record_session(p1, 300, seed=5)
    np.testing.assert_array_equal(s1.psi, s2.psi)
    np.testing.assert_array_equal(s1.pinch, s2.pinch)


def test_session_free_and_pinch_poses() -> None:
    person = PersonParams.sample("p4")
    s = record_session(person, 600, pinch_fraction=0.4, seed=1)
    assert s.theta.shape == s.psi.shape == (600, 10) and s.pinch.sum() == 240
    lo = np.array([JOINT_RANGES[n][0] for n in JOINT_NAMES])
    hi = np.array([JOINT_RANGES[n][1] for n in JOINT_NAMES])
    assert np.all((s.theta >= lo) & (s.theta <= hi))
    gap = fingertip_gap(s.theta, person)
    assert np.all(gap[~s.pinch] >= FREE_MIN_GAP)
    force = pinch_force(s.theta, person)
    assert np.all(force[~s.pinch] == 0.0)
    np.testing.assert_allclose(
        [force[s.pinch].min(), force[s.pinch].max()], PINCH_FORCE_RANGE, atol=0.1
    )
    # Natural poses: DIP follows PIP; in a pinch it does not.
    i2, i3 = joint_index("index_pip"), joint_index("index_dip")
    free = s.theta[~s.pinch]
    inside = free[:, i3] < 1.15  # not clipped at the range
    residual = free[inside, i3] - person.dip_coupling * free[inside, i2]
    assert np.abs(residual).max() < 0.1
    pinch = s.theta[s.pinch]
    assert np.abs(pinch[:, i3] - person.dip_coupling * pinch[:, i2]).mean() > 0.2
    train, test = s.split(0.25, seed=0)
    assert len(train) + len(test) == 600 and test.pinch.sum() == 60


# --- calibration --------------------------------------------------------------------------


def test_linear_calibration_is_good_on_free_poses_but_fails_in_pinch(
    p2_session: tuple[CalibrationSession, CalibrationSession],
) -> None:
    """Paper 4.1: optimal linear gains work until thumb and index touch (the coupling)."""
    train, test = p2_session
    tuned = evaluate(fit_linear(train.subset(~train.pinch)), test)
    assert tuned.free_rms_deg < 1.0
    assert tuned.pinch_rms_deg > 4.0 and tuned.pinch_rms_deg > 5 * tuned.free_rms_deg
    assert tuned.pinch_gap_mm > 5.0
    mixed = evaluate(fit_linear(train), test)  # fitted on pinches too: still bad there
    assert mixed.pinch_rms_deg > 4.0 and mixed.pinch_rms_deg > 1.5 * mixed.free_rms_deg


def test_ann_beats_linear_in_pinch(
    p2_session: tuple[CalibrationSession, CalibrationSession], p2_ann: Calibration
) -> None:
    train, test = p2_session
    ann, linear = evaluate(p2_ann, test), evaluate(fit_linear(train, LINEAR_GROUPS), test)
    assert ann.rms_deg < 2.0
    assert linear.pinch_rms_deg >= 3.0 * ann.pinch_rms_deg
    assert ann.pinch_gap_mm < 3.0 < linear.pinch_gap_mm


def test_predict_shapes_folding_and_bad_input(
    p2_session: tuple[CalibrationSession, CalibrationSession], p2_ann: Calibration
) -> None:
    psi = p2_session[1].psi
    batch = p2_ann.predict(psi)
    assert batch.shape == (len(psi), 10) and batch.dtype == np.float64
    np.testing.assert_allclose(batch, p2_ann.predict_groupwise(psi), rtol=0, atol=1e-12)
    np.testing.assert_allclose(p2_ann.predict(psi[3]), batch[3], rtol=0, atol=1e-12)
    for bad in (np.zeros(9), np.zeros((2, 3, 10))):
        with pytest.raises(ValueError, match="shape"):
            p2_ann.predict(bad)
    reading = psi[0].copy()
    reading[4] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        p2_ann.predict(reading)
    assert p2_ann.describe() == "wrist linear 3-3, index 5-24-3, thumb 5-12-2, fingers linear 2-2"


def test_training_is_deterministic() -> None:
    train, _ = record_session(PersonParams.sample("p5"), 300, seed=2).split()
    a, _ = train_calibration(train, max_iter=30, seed=4)
    b, _ = train_calibration(train, max_iter=30, seed=4)
    for ga, gb in zip(a.groups, b.groups, strict=True):
        for (wa, ba), (wb, bb) in zip(ga.layers, gb.layers, strict=True):
            np.testing.assert_array_equal(wa, wb)
            np.testing.assert_array_equal(ba, bb)


# --- profiles -----------------------------------------------------------------------------


def test_profile_round_trip_is_bit_identical(
    profile_file: Path,
    p2_session: tuple[CalibrationSession, CalibrationSession],
    p2_ann: Calibration,
) -> None:
    loaded = load_profile(profile_file, glove_id=GLOVE, person_id="p2")
    psi = p2_session[1].psi
    np.testing.assert_array_equal(loaded.predict(psi), p2_ann.predict(psi))
    assert loaded.person_id == "p2" and loaded.glove_id == GLOVE and loaded.model_kind == "ann"
    assert loaded.held_out == evaluate(p2_ann, p2_session[1])
    data = json.loads(profile_file.read_text())
    assert data["schema_version"] == SCHEMA_VERSION and data["n_readings"] == 10
    assert data["created"].endswith("+00:00")
    assert {"x_mean", "x_scale", "y_mean", "y_scale"} <= set(data["groups"][1])
    assert sorted(os.listdir(profile_file.parent)) == ["profile_p2.json"]  # no temp files


def _edit(path: Path, tmp_path: Path, change: Any) -> Path:
    data = json.loads(path.read_text())
    change(data)
    out = tmp_path / "edited.json"
    out.write_text(json.dumps(data))
    return out


def _set(key: str, value: Any) -> Any:
    return lambda d: d.__setitem__(key, value)


def _drop_group(d: dict[str, Any]) -> None:
    d["groups"].pop(0)


def _bad_shape(d: dict[str, Any]) -> None:
    d["groups"][1]["layers"][0]["weight"].pop()


def _bad_number(d: dict[str, Any]) -> None:
    d["groups"][1]["layers"][1]["bias"][0] = "0.5"


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (_set("schema_version", SCHEMA_VERSION + 1), "schema version 2.*upgrade ias-gym"),
        (_set("schema_version", 0), "schema version 0.*calibrate"),
        (_set("format", "something-else"), "not a glove profile"),
        (_set("n_readings", 12), "12 readings.*this glove sends 10"),
        (_set("sensor_names", SENSOR_NAMES[:9]), "10 readings \\(9 sensor names\\)"),
        (_set("glove_id", "other-glove"), "glove 'other-glove', not for this glove"),
        (_set("created", "yesterday"), "ISO 8601"),
        (_set("model_kind", "linear"), "model_kind 'linear'"),
        (_drop_group, "every joint exactly once; missing \\['wrist_deviation'"),
        (_bad_shape, "layer 0 has W \\(23, 5\\)"),
        (_bad_number, "list of finite numbers"),
        (lambda d: d.pop("held_out"), "has no 'held_out'"),
        (lambda d: d["groups"][0].__setitem__("kind", "svm"), "kind must be one of"),
    ],
)
def test_malformed_or_mismatched_profiles_raise_profile_error(
    profile_file: Path, tmp_path: Path, change: Any, expected: str
) -> None:
    path = _edit(profile_file, tmp_path, change)
    with pytest.raises(ProfileError, match=expected) as info:
        load_profile(path, glove_id=GLOVE)
    assert str(path) in str(info.value)


def test_truncated_missing_and_garbage_profiles(profile_file: Path, tmp_path: Path) -> None:
    raw = profile_file.read_bytes()
    cases = {
        "truncated.json": (raw[: len(raw) // 2], "not valid JSON.*truncated"),
        "empty.json": (b"", "not valid JSON"),
        "binary.json": (b"\x93NUMPY\x01\x00\xff", "not UTF-8"),
        "nan.json": (raw.replace(b'"x_mean": [', b'"x_mean": [NaN, ', 1), "non-finite"),
        "list.json": (b"[1, 2, 3]", "top level must be a JSON object"),
    }
    for name, (content, expected) in cases.items():
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(ProfileError, match=expected):
            load_profile(path)
    with pytest.raises(ProfileError, match=r"no such file.*ias-gym calibrate"):
        load_profile(tmp_path / "missing.json")
    with pytest.raises(ProfileError, match="belongs to person 'p2', not 'p3'"):
        load_profile(profile_file, person_id="p3")
    with pytest.raises(ProfileError, match="this glove sends 11"):
        load_profile(profile_file, n_readings=11)


def test_save_is_atomic(
    profile_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    profile = load_profile(profile_file)
    target = tmp_path / "p.json"
    save_profile(profile, target)
    before = target.read_bytes()

    def crash(src: str, dst: str) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", crash)
    with pytest.raises(OSError, match="disk full"):
        save_profile(Profile("p9", GLOVE, profile.calibration, profile.held_out), target)
    assert target.read_bytes() == before
    assert os.listdir(tmp_path) == ["p.json"]


def test_inference_never_imports_torch(profile_file: Path) -> None:
    code = textwrap.dedent(
        f"""
        import sys
        import numpy as np
        from ias_gym.glove import load_profile
        profile = load_profile({str(profile_file)!r}, glove_id={GLOVE!r})
        theta = profile.predict(np.zeros(10))
        assert theta.shape == (10,) and np.isfinite(theta).all()
        heavy = sorted(m for m in ("torch", "mujoco", "matplotlib") if m in sys.modules)
        print("imported:", heavy)
        """
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    )
    assert result.stdout.strip() == "imported: []"


def test_missing_torch_names_the_extra() -> None:
    code = (
        "import sys; sys.modules['torch'] = None\n"
        "try:\n    import ias_gym.glove.training\n"
        "except ImportError as e:\n    print(e)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout
    assert "pip install 'ias-gym[glove]'" in out


# --- devices ------------------------------------------------------------------------------


def test_simulated_glove_context_manager_clock_and_feedback() -> None:
    person = PersonParams.sample("p1")
    operator = ReachPinchLift(person)
    with SimulatedGlove(person, operator, seed=3, rate_hz=50.0) as glove:
        assert isinstance(glove, GloveDevice) and glove.n_actuators == len(ACTUATED_JOINTS) == 5
        readings = [glove.read() for _ in range(5)]
        assert [r.timestamp for r in readings] == [k / 50.0 for k in range(5)]
        assert all(r.psi.shape == (10,) and r.psi.dtype == np.float64 for r in readings)
        glove.write_feedback([0.1, 0.0, -0.2, 0.0, 0.9])
        for bad in ([np.nan, 0, 0, 0, 0], [0, 0, np.inf, 0, 0], [0.0] * 4, [[0.0] * 5]):
            with pytest.raises(ValueError):
                glove.write_feedback(bad)
        assert len(glove.feedback) == 1
        t, torques = glove.feedback[0]
        assert t == 4 / 50.0
        np.testing.assert_array_equal(torques, [0.1, 0.0, -0.2, 0.0, 0.5])  # saturated
    assert glove.closed
    with pytest.raises(RuntimeError, match="closed"):
        glove.read()
    # Noise-free, the glove reads exactly the sensor model of the operator's pose.
    quiet = SimulatedGlove(person, operator, noise=False, rate_hz=10.0)
    for _ in range(25):
        r = quiet.read()
        np.testing.assert_array_equal(r.psi, sensor_readings(operator(r.timestamp), person))
    quiet.close()


def test_reach_pinch_lift_is_a_plausible_trajectory() -> None:
    person = PersonParams.sample("p3")
    op = ReachPinchLift(person, pinch_force=2.0)
    t = np.arange(0.0, 5.0, 0.01)
    theta = np.array([op(ti) for ti in t])
    lo = np.array([JOINT_RANGES[n][0] for n in JOINT_NAMES])
    hi = np.array([JOINT_RANGES[n][1] for n in JOINT_NAMES])
    assert np.all((theta >= lo - 1e-12) & (theta <= hi + 1e-12))
    assert np.abs(np.diff(theta, axis=0)).max() < 0.03  # smooth: < 3 rad/s
    phases = [op.phase(ti) for ti in t]
    assert list(dict.fromkeys(phases)) == ["rest", "reach", "close", "hold", "lift", "hold_lifted"]
    gap = fingertip_gap(theta, person)
    force = pinch_force(theta, person)
    holding = np.isin(phases, ["hold", "lift", "hold_lifted"])
    assert np.all(gap[np.isin(phases, ["rest", "reach"])] > 0.02)  # apart before the pinch
    np.testing.assert_allclose(force[holding], 2.0, atol=1e-9)  # pads pressed while holding
    wf = joint_index("wrist_flexion")
    assert theta[-1, wf] < theta[np.flatnonzero(holding)[0], wf] - 0.25  # wrist lifted


def test_calibrated_glove_tracks_the_operator(profile_file: Path) -> None:
    person = PersonParams.sample("p2")
    profile = load_profile(profile_file)
    op = ReachPinchLift(person)
    with SimulatedGlove(person, op, seed=0, rate_hz=20.0) as glove:
        errors = []
        for _ in range(100):
            r = glove.read()
            errors.append(profile.predict(r.psi) - op(r.timestamp))
    assert np.rad2deg(np.sqrt(np.mean(np.square(errors)))) < 3.0


# --- CLI ----------------------------------------------------------------------------------


def test_calibrate_json_last_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    parser = argparse.ArgumentParser(prog="ias-gym")
    add_glove_commands(parser.add_subparsers(dest="command", required=True))
    argv = ["calibrate", "--person", "p1", "--out", str(tmp_path), "--json"]
    args = parser.parse_args([*argv, "--readings", "600", "--max-iter", "60"])
    assert args.run(args) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    summary = json.loads(lines[-1])
    keys = (
        "ann_rms_deg",
        "linear_rms_deg",
        "ann_pinch_rms_deg",
        "linear_pinch_rms_deg",
        "ann_pinch_gap_mm",
        "linear_pinch_gap_mm",
    )
    assert all(isinstance(summary[k], float) and summary[k] > 0 for k in keys)
    profile, figure = tmp_path / "profile_p1.json", tmp_path / "calibration_p1.png"
    assert any(str(profile) in line for line in lines) and any(
        str(figure) in line for line in lines
    )
    assert figure.stat().st_size > 10_000
    assert load_profile(profile).held_out.rms_deg == summary["ann_rms_deg"]
    bad = parser.parse_args(["calibrate", "--person", "../x", "--out", str(tmp_path)])
    with pytest.raises(InputError, match=r"--person '\.\./x' is not a valid id"):
        bad.run(bad)

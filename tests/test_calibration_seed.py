"""IAS_GYM_CALIBRATION_SEED: the cached calibrations trained under another seed, in files of
their own (what `make test-perturbed` runs the closed-loop tests with)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

import ias_gym.glove.training as training
from ias_gym.errors import InputError
from ias_gym.glove.hand import PersonParams
from ias_gym.glove.profile import load_profile
from ias_gym.glove.profile_cache import CALIBRATION_SEED_VAR, calibration_seed, default_calibration


@pytest.fixture()
def quick_training(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """An empty cache under tmp_path, and the calibration trained on few readings and
    iterations (the same procedure, a second instead of seconds); the training seeds."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    seeds: list[int] = []
    real = training.calibrate_person

    def quick(person: PersonParams, **kwargs: Any) -> training.CalibrationRun:
        seeds.append(kwargs["seed"])
        return real(person, **{**kwargs, "n_readings": 200, "max_iter": 30})

    monkeypatch.setattr(training, "calibrate_person", quick)
    return seeds


def test_the_calibration_seed_trains_another_calibration_beside_the_default(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, quick_training: list[int]
) -> None:
    person = PersonParams.sample("p1")
    folder = tmp_path / "ias_gym" / "glove_profiles"
    psi = np.random.default_rng(0).normal(0.0, 0.3, size=(20, 10))
    monkeypatch.delenv(CALIBRATION_SEED_VAR, raising=False)
    default = default_calibration(person, progress=False)
    monkeypatch.setenv(CALIBRATION_SEED_VAR, "7")
    other = default_calibration(person, progress=False)
    assert quick_training == [0, 7]
    names = sorted(p.name for p in folder.iterdir())
    assert len(names) == 2 and names[0].startswith("p1-seed0-")
    assert names[0].endswith("-calibration7.json") and names[1] == names[0].replace(
        "-calibration7", ""
    )
    profile = load_profile(folder / names[0], person_id="p1")
    assert profile.training is not None and profile.training["seed"] == 7
    assert not np.allclose(other.predict(psi), default.predict(psi))
    # each is cached: loaded again, not trained again, and the default file is untouched
    np.testing.assert_array_equal(default_calibration(person).predict(psi), other.predict(psi))
    monkeypatch.delenv(CALIBRATION_SEED_VAR)
    np.testing.assert_array_equal(default_calibration(person).predict(psi), default.predict(psi))
    assert quick_training == [0, 7]


def test_the_calibration_seed_must_be_a_seed(monkeypatch: pytest.MonkeyPatch) -> None:
    for unset in ("", "  "):
        monkeypatch.setenv(CALIBRATION_SEED_VAR, unset)
        assert calibration_seed() is None
    monkeypatch.setenv(CALIBRATION_SEED_VAR, "3")
    assert calibration_seed() == 3
    for bad in ("x", "-2", "0.5"):
        monkeypatch.setenv(CALIBRATION_SEED_VAR, bad)
        with pytest.raises(InputError, match=CALIBRATION_SEED_VAR):
            calibration_seed()

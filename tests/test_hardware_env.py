"""The hardware env IAS-GloveHardware-v0 (ias_gym.hardware.env): the profile kwarg, the
Gymnasium checker, a session recorded as a skill, its recording never overwriting a file
(python-can's virtual bus with the emulator, no hardware). Every warning is an error
here, and so is any python-can log record at WARNING or above."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import can
import gymnasium as gym
import numpy as np
import pytest

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.cli import main
from ias_gym.errors import InputError
from ias_gym.hardware import (
    CanGlove,
    GloveEmulator,
    GloveHardwareEnv,
    ReplayGlove,
)

pytestmark = [
    pytest.mark.realtime,
    pytest.mark.filterwarnings("error"),
    pytest.mark.usefixtures("no_python_can_warnings", "no_gc_pauses"),
]


def test_profile_kwarg_sets_person_and_calibration(channel: str, tmp_path: Path) -> None:
    from ias_gym.glove.calibration import evaluate
    from ias_gym.glove.hand import PersonParams
    from ias_gym.glove.profile import DEFAULT_GLOVE_ID, Profile, ProfileError, save_profile
    from ias_gym.glove.profile_cache import default_calibration
    from ias_gym.glove.sensor_model import record_session

    person = PersonParams.sample("p1")
    calibration = default_calibration(person)
    session = record_session(person, 50, seed=1)
    metrics = evaluate(calibration, session)
    profile = Profile("p1", DEFAULT_GLOVE_ID, calibration, metrics)
    path = save_profile(profile, tmp_path / "p1.json")
    with GloveEmulator(channel=channel, rate_hz=500, person=person):
        env = GloveHardwareEnv(channel=channel, profile=path, control_dt=0.002)
        try:
            assert env.person.person_id == "p1"
            np.testing.assert_allclose(
                env.calibration.predict(session.psi), calibration.predict(session.psi)
            )
        finally:
            env.close()
        with pytest.raises(ProfileError, match="glove"):
            GloveHardwareEnv(channel=channel, profile=path, glove_id="another-glove")


def test_hardware_env_passes_the_gymnasium_checker(channel: str) -> None:
    from gymnasium.utils.env_checker import check_env

    with GloveEmulator(channel=channel, rate_hz=500):
        env = gym.make("IAS-GloveHardware-v0", channel=channel, control_dt=0.002)
        try:
            with warnings.catch_warnings():  # its only complaint: the obs space is unbounded
                warnings.filterwarnings("ignore", "(?s).*Box observation space", UserWarning)
                check_env(env.unwrapped, skip_render_check=True)
        finally:
            env.close()


def test_a_can_glove_session_is_recorded_as_a_skill(channel: str, tmp_path: Path) -> None:
    from ias_gym.skills import SkillDB
    from ias_gym.skills.record import record_skills_spec

    db = tmp_path / "skills.db"
    # Watchdogs of 0.2 s: this tests the recording, not the 20 ms watchdog
    # (tests/test_can_glove.py does), and the interpreter can stall longer late in the suite.
    with GloveEmulator(channel=channel, rate_hz=500, watchdog_timeout=0.2):
        (skill_id,) = record_skills_spec(
            "IAS-GloveHardware-v0",
            "teleop",
            1,
            db,
            progress=False,
            env_kwargs={
                "channel": channel,
                "control_dt": 0.004,
                "duration": 1.2,
                "watchdog_timeout": 0.2,
            },
        )
    with SkillDB(db) as skills:
        skill = skills.get(skill_id)
    assert skill.task == "IAS-GloveHardware-v0" and skill.person_id == "p1"
    assert skill.source.startswith("glove:")
    model = skill.model
    assert model.time.shape[0] == skill.demonstration.length + 1 == 301
    touching = model.touching.all(axis=1)  # index and thumb on the pen
    assert touching[-50:].all()  # the pinch closes within the 1.2 s
    assert np.isfinite(model.c[touching]).all()


def test_skills_record_says_when_the_can_glove_is_silent(
    channel: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    kwargs = json.dumps({"channel": channel})
    code = main(
        ["skills", "record", "--env", "IAS-GloveHardware-v0", "--policy", "teleop",
         "--db", str(tmp_path / "s.db"), "--env-kwargs", kwargs, "--no-progress"]
    )  # fmt: skip
    assert code != 0 and "glove-emulator" in capsys.readouterr().err


def test_a_recording_never_overwrites_an_existing_file(
    channel: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``record=`` on an existing file (maybe a person's only session) is refused when the env
    is made, before a bus is opened; ``overwrite=True`` replaces it."""
    keep = tmp_path / "keep.blf"
    keep.write_bytes(b"a real person's session")

    def no_bus(*args: object, **kwargs: object) -> None:
        raise AssertionError("a bus was opened before the record file was checked")

    with monkeypatch.context() as m:
        m.setattr(can, "Bus", no_bus)
        with pytest.raises(InputError, match=r"keep\.blf.*overwrite=True"):
            gym.make("IAS-GloveHardware-v0", channel=channel, record=keep)
        with pytest.raises(InputError, match=r"keep\.blf.*overwrite=True"):
            CanGlove(channel=channel, log_path=keep)
        for bad, match in (
            (tmp_path / "s.csv", r"\.asc, \.blf, \.log"),
            (tmp_path / "nowhere" / "s.blf", "does not exist"),
            (tmp_path, "choose one of these suffixes"),
        ):
            with pytest.raises(InputError, match=match):
                gym.make("IAS-GloveHardware-v0", channel=channel, record=bad)
    assert keep.read_bytes() == b"a real person's session"
    with GloveEmulator(channel=channel, rate_hz=500):
        env = gym.make(
            "IAS-GloveHardware-v0", channel=channel, record=keep, overwrite=True, control_dt=0.004
        )
        env.reset(seed=0)
        for _ in range(20):
            env.step(np.zeros(10, dtype=np.float32))
        env.close()
    assert len(ReplayGlove(keep)) == 21
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.blf"]  # no partial file left

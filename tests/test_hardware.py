"""The glove on a CAN bus: protocol, device, watchdog, emulator, replay (python-can's virtual
bus, no hardware). Every warning is an error here, and so is any python-can log record at
WARNING or above (its "was not properly shut down" is a log record, not a warning)."""

from __future__ import annotations

import gc
import itertools
import json
import logging
import time
import warnings
from collections.abc import Iterator
from dataclasses import astuple
from pathlib import Path

import can
import cantools
import gymnasium as gym
import numpy as np
import pytest

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.cli import main
from ias_gym.glove.device import ACTUATED_JOINTS, MAX_FEEDBACK_TORQUE
from ias_gym.glove.hand import SENSOR_NAMES
from ias_gym.hardware import (
    DBC_PATH,
    CanGlove,
    FaultInjection,
    FrameReceiver,
    GloveEmulator,
    GloveHardwareEnv,
    GloveTimeoutError,
    ReplayError,
    ReplayGlove,
    Sample,
    bus_load,
    database,
)
from ias_gym.hardware.protocol import (
    SENSORS_A,
    SENSORS_B,
    TORQUE_COMMAND,
    ProtocolError,
    UnknownIdError,
    decode_frame,
    encode_sensors,
    encode_torque,
    frame_id,
    in_sensor_range,
    torques_of,
)

pytestmark = pytest.mark.filterwarnings("error")

_channels = itertools.count()


@pytest.fixture
def channel() -> str:
    """A virtual-bus channel of this test alone."""
    return f"ias-test-{next(_channels)}"


@pytest.fixture(autouse=True)
def no_python_can_warnings(caplog: pytest.LogCaptureFixture) -> Iterator[None]:
    caplog.set_level(logging.WARNING, logger="can")
    yield
    records = caplog.get_records("setup") + caplog.get_records("call")
    bad = [r.getMessage() for r in records if r.name.startswith("can")]
    assert not bad, bad


def spy(channel: str) -> can.BusABC:
    return can.Bus(interface="virtual", channel=channel)


def drain(bus: can.BusABC) -> list[can.Message]:
    out = []
    while (msg := bus.recv(timeout=0.0)) is not None:
        out.append(msg)
    return out


# --------------------------------------------------------------------------- the DBC
def test_dbc_describes_the_glove() -> None:
    db = database()
    assert DBC_PATH.is_file()
    assert db.buses[0].baudrate == 1_000_000
    torque = db.get_message_by_name(TORQUE_COMMAND)
    assert "Torque" in torque.name
    for joint in ACTUATED_JOINTS:  # ranges = the actuators' limits
        s = torque.get_signal_by_name(joint)
        assert (s.minimum, s.maximum) == (-MAX_FEEDBACK_TORQUE, MAX_FEEDBACK_TORQUE)
    classic = {s.name for m in (SENSORS_A, SENSORS_B) for s in db.get_message_by_name(m).signals}
    fd = {s.name for s in db.get_message_by_name("GloveSensorsFD").signals}
    assert classic == fd == {*SENSOR_NAMES, "Counter"}
    for name in (SENSORS_A, SENSORS_B, "GloveSensorsFD"):
        counter = db.get_message_by_name(name).get_signal_by_name("Counter")
        assert (counter.length, counter.minimum, counter.maximum) == (8, 0, 255)
    assert db.get_message_by_name("GloveSensorsFD").is_fd
    assert all(m.length <= 8 for m in db.messages if not m.is_fd)
    status = db.get_message_by_name("GloveStatus")
    assert {"TorqueEnabled", "FaultWatchdog"} <= {s.name for s in status.signals}
    assert "Enable" in {s.name for s in db.get_message_by_name("HostCommand").signals}


def test_sensor_and_torque_frames_match_byte_fixtures() -> None:
    psi = np.array([-0.1, 0.2, -0.3, 0.4, 0.5, 0.6, 0.7, 1.8, 0.9, 1.0])
    a, b = encode_sensors(psi, 7)
    assert (a.arbitration_id, a.data.hex()) == (0x110, "07ee229ca2d0a741")
    assert (b.arbitration_id, b.data.hex()) == (0x111, "074cf423a9c54951")
    (f,) = encode_sensors(psi, 7, fd=True)
    assert f.is_fd and f.data.hex() == "07983a5046c832204e0852f055d859d084a8619065000000"
    cmd, sent = encode_torque([0.1, -0.2, 0.5, -0.5, 0.0], 3, 200)
    assert (cmd.arbitration_id, cmd.data.hex()) == (0x100, "64e04c1f83000c32")
    np.testing.assert_array_equal(sent, [0.1, -0.2, 0.5, -0.5, 0.0])
    receiver = FrameReceiver()
    assert receiver.feed(a.arbitration_id, a.data) is None  # half a sample
    sample = receiver.feed(b.arbitration_id, b.data)
    assert isinstance(sample, Sample) and sample.counter == 7
    np.testing.assert_allclose(sample.psi, psi, atol=0.001 + 1e-12)  # 2 mrad steps
    assert in_sensor_range(psi) and in_sensor_range(psi, fd=True)
    high = psi.copy()
    high[7] = 2.45  # thumb_web beyond its converter's 2.4 rad: saturated on the wire
    assert not in_sensor_range(high)
    wire = decode_frame(*astuple(encode_sensors(high, 8)[1])[:2]).values["thumb_web"]
    assert wire == pytest.approx(2.4)


@pytest.mark.parametrize("seed", range(5))
def test_every_message_round_trips(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for msg in database().messages:
        values = {
            s.name: float(rng.uniform(s.minimum, s.maximum))
            if s.scale != 1
            else int(rng.integers(s.minimum, s.maximum + 1))
            for s in msg.signals
        }
        data = msg.encode(values, strict=True)
        decoded = decode_frame(msg.frame_id, data)
        assert decoded.name == msg.name
        for s in msg.signals:
            assert decoded.values[s.name] == pytest.approx(values[s.name], abs=s.scale / 2 + 1e-9)


def test_strict_ranges_both_ways() -> None:
    sent = encode_torque([0.9, -3.0, np.nan, np.inf, -np.inf], 1, 0)[1]
    np.testing.assert_array_equal(sent, [0.5, -0.5, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="shape"):
        encode_torque([0.1, 0.2], 1, 0)
    with pytest.raises(cantools.database.EncodeError, match=r"smaller than or equal to 0\.5"):
        database().get_message_by_name(TORQUE_COMMAND).encode(
            {**dict.fromkeys(ACTUATED_JOINTS, 0.0), "index_mcp": 0.6, "Counter": 0,
             "SampleCounter": 0},
            strict=True,
        )  # fmt: skip
    # cantools decodes raw values beyond the DBC's range without complaint; we do not.
    top = bytes([0x00] + [0xFF] * 7)  # every reading at raw 2047 = 2.494 rad > 2.4
    with pytest.raises(ProtocolError, match="outside"):
        decode_frame(frame_id(SENSORS_A), top)
    raw = bytearray(encode_torque(np.zeros(5), 1, 0)[0].data)
    raw[0], raw[1] = 0xF6, 0x01  # index_mcp raw 502 = 0.502 N m
    with pytest.raises(ProtocolError, match="index_mcp"):
        decode_frame(frame_id(TORQUE_COMMAND), bytes(raw))
    with pytest.raises(ProtocolError, match="data bytes"):
        decode_frame(frame_id(SENSORS_A), b"\x00" * 7)
    with pytest.raises(UnknownIdError, match="unknown"):
        decode_frame(0x7FF, b"\x00" * 8)


def test_receiver_counts_drops_duplicates_and_bad_frames() -> None:
    psi = np.linspace(0.0, 1.0, 10)
    r = FrameReceiver()
    frames = {c: encode_sensors(psi, c) for c in range(6)}
    samples = []
    for c, parts in ((0, "AB"), (1, "AB"), (1, "B"), (2, "B"), (4, "AB"), (5, "A")):
        for p in parts:
            f = frames[c]["AB".index(p)]
            out = r.feed(f.arbitration_id, f.data)
            if isinstance(out, Sample):
                samples.append(out.counter)
    r.feed(0x110, b"\x01\x02")  # wrong length
    r.feed(0x123, b"\x00")  # another node
    r.feed(0, b"", is_error_frame=True)
    s = r.stats
    assert samples == [0, 1, 4]  # 2 lost its A half, 3 is gone, 5 lacks its B half
    # A: 0 1 4 5 -> 2 missing (2, 3); B: 0 1 [1 dup] 2 4 -> 1 missing (3)
    assert (s.frames_dropped, s.frames_duplicated) == (3, 1)
    assert (s.frames_invalid, s.frames_unknown, s.error_frames) == (1, 1, 1)


def test_bus_load_of_the_protocol() -> None:
    # Per sample at 1 kHz: A, B and TorqueCommand (8 bytes: 111 bits + up to 24 stuff
    # bits), GloveStatus (1 byte: 55 + 10) at 50 Hz, 1 Mbit/s.
    load = bus_load(1000.0)
    assert load["total"] == pytest.approx((3 * 135 * 1000 + 65 * 50) / 1e6)
    assert bus_load(1000.0, worst_case=False)["total"] == pytest.approx(
        (3 * 111 * 1000 + 55 * 50) / 1e6
    )
    assert bus_load(1000.0, fd=True)["total"] < load["total"]  # one FD frame, 5 Mbit/s data


# --------------------------------------------------------------------------- live, virtual bus
@pytest.mark.parametrize("fd", [False, True], ids=["classic", "fd"])
def test_glove_reads_samples_and_the_emulator_applies_torques(channel: str, fd: bool) -> None:
    with (
        GloveEmulator(channel=channel, rate_hz=500, fd=fd) as emu,
        CanGlove(channel=channel, fd=fd) as glove,
    ):
        first = glove.read()
        assert first.psi.shape == (10,) and np.isfinite(first.psi).all()
        glove.enable()
        command = np.array([0.1, -0.2, 0.3, 0.0, 0.05])
        for _ in range(20):
            glove.read()
            glove.write_feedback(command)
            time.sleep(0.002)
        time.sleep(0.01)
        np.testing.assert_allclose(emu.torque, command, atol=5e-4)
        assert emu.torque_enabled and emu.stats.commands == 20
        assert max(emu.command_age) <= 3  # the echoed sample was at most 3 samples old
        status = glove.device_status
        assert status is not None and status["TorqueEnabled"] == 1
        glove.write_feedback([np.nan, 0.2, np.inf, 9.0, -9.0])
        np.testing.assert_array_equal(glove.last_command, [0.0, 0.2, 0.0, 0.5, -0.5])
        assert glove.nonfinite_commands == 1
        with pytest.raises(ValueError, match="shape"):
            glove.write_feedback([0.1])
        s = glove.stats
        assert s.samples > 0 and s.frames_invalid == s.frames_dropped == 0
        # one frame per sample with CAN FD, two with classic CAN (+ 50 Hz status)
        assert s.frames_received < (1.2 if fd else 2.2) * s.samples


def test_a_closed_glove_refuses_to_read(channel: str) -> None:
    glove = CanGlove(channel=channel)
    glove.close()
    with pytest.raises(RuntimeError, match="closed"):
        glove.read()


def test_startup_timeout_says_what_to_check(channel: str) -> None:
    with (
        CanGlove(channel=channel, startup_timeout=0.05) as glove,
        pytest.raises(GloveTimeoutError, match="glove-emulator"),
    ):
        glove.read()


def test_device_watchdog_turns_torque_off_without_commands(channel: str) -> None:
    with GloveEmulator(channel=channel, rate_hz=500) as emu, CanGlove(channel=channel) as glove:
        glove.read()
        glove.enable()
        glove.write_feedback(np.full(5, 0.2))
        time.sleep(0.01)
        assert emu.torque_enabled and emu.torque.max() == pytest.approx(0.2)
        time.sleep(0.08)  # the host goes quiet: no command for 80 ms
        assert not emu.torque_enabled and not emu.torque.any() and emu.fault_watchdog
        time.sleep(0.05)
        status = glove.device_status
        assert status is not None and status["FaultWatchdog"] == 1
        assert emu.stats.watchdog_trips == 1
        glove.enable()  # the explicit re-enable clears it
        glove.write_feedback(np.full(5, 0.1))
        time.sleep(0.01)
        assert emu.torque_enabled and not emu.fault_watchdog


def test_fault_injection_never_lets_torque_out_of_range(channel: str) -> None:
    """5 % dropped, 1 % corrupted, wrong lengths, garbage on protocol ids, error frames,
    then 100 ms of silence: no command leaves the DBC's limits, the watchdog trips within its
    time plus one period, nothing is raised, and torque stays off until the re-enable."""
    faults = FaultInjection(
        drop=0.05, corrupt=0.01, wrong_length=0.01, garbage=0.01, error_frame=0.01, seed=3
    )
    rate = 500.0
    watch = spy(channel)
    try:
        with GloveEmulator(channel=channel, rate_hz=rate, faults=faults) as emu:
            env = GloveHardwareEnv(channel=channel, control_dt=0.002, duration=10.0)
            try:
                env.reset(seed=0)
                rng = np.random.default_rng(0)
                for _ in range(400):  # 0.8 s
                    _, _, _, truncated, info = env.step(rng.uniform(-1, 1, 10))
                    assert not truncated, info["fault"]
                emu.pause(0.1)
                faulted = []
                for _ in range(100):
                    _, _, _, truncated, info = env.step(rng.uniform(-1, 1, 10))
                    faulted.append(bool(info["fault"]))
                    if truncated:
                        break
                assert truncated and "watchdog" in info["fault"]
                glove = env.device
                assert isinstance(glove, CanGlove)
                assert glove.watchdog_trips == 1
                assert glove.trip_delays[0] <= glove.watchdog_timeout + 1.0 / rate
                # while off, every command is zero whatever the env computes
                time.sleep(0.12)  # the glove speaks again; still off
                for _ in range(5):
                    env.step(np.ones(10))
                    assert not glove.last_command.any()
                env.reset(seed=1)  # the explicit re-enable
                assert glove.fault is None
                stats = glove.stats
                assert glove.bus_errors == 0, glove.last_error
            finally:
                env.close()
        assert stats.frames_dropped > 0 and stats.frames_invalid > 0 and stats.error_frames > 0
        assert emu.stats.commands_rejected == 0
        sent = [m for m in drain(watch) if m.arbitration_id == frame_id(TORQUE_COMMAND)]
        assert len(sent) > 400
        msg = database().get_message_by_name(TORQUE_COMMAND)
        for m in sent:  # decoded without our range check: the raw truth on the wire
            values = msg.decode(m.data, decode_choices=False)
            assert all(abs(values[j]) <= MAX_FEEDBACK_TORQUE for j in ACTUATED_JOINTS)
        # the last frame of the session: zero torque
        assert not torques_of(decode_frame(sent[-1].arbitration_id, sent[-1].data)).any()
    finally:
        watch.shutdown()


def test_close_sends_zero_torque_and_shuts_down(channel: str) -> None:
    watch = spy(channel)
    try:
        with GloveEmulator(channel=channel, rate_hz=500):
            glove = CanGlove(channel=channel)
            glove.read()
            glove.enable()
            glove.write_feedback(np.full(5, 0.3))
            drain(watch)
            glove.close()
            glove.close()  # idempotent
            assert not glove._thread.is_alive()
            del glove
            gc.collect()  # python-can warns from the bus's __del__ if it was not shut down
            tail = [m for m in drain(watch) if m.arbitration_id in (0x080, 0x100)]
    finally:
        watch.shutdown()
    names = [decode_frame(m.arbitration_id, m.data) for m in tail]
    assert [d.name for d in names] == [TORQUE_COMMAND, "HostCommand"]
    assert not torques_of(names[0]).any() and names[1].values["Enable"] == 0


# --------------------------------------------------------------------------- env, record, replay
@pytest.mark.parametrize("suffix", [".asc", ".blf"])
def test_recorded_session_replays_to_identical_observations(
    channel: str, tmp_path: Path, suffix: str
) -> None:
    log = tmp_path / f"session{suffix}"
    live: list[np.ndarray] = []
    with GloveEmulator(channel=channel, rate_hz=500):
        env = gym.make("IAS-GloveHardware-v0", channel=channel, record=log, control_dt=0.004)
        for seed in (0, 1):  # two episodes in one log
            obs, _ = env.reset(seed=seed)
            live.append(obs)
            for _ in range(150):
                live.append(env.step(np.zeros(10, dtype=np.float32))[0])
        env.close()
    replay = gym.make("IAS-GloveHardware-v0", replay=log, control_dt=0.004)
    replayed = []
    for seed in (0, 1):
        obs, _ = replay.reset(seed=seed)
        replayed.append(obs)
        for _ in range(150):
            replayed.append(replay.step(np.zeros(10, dtype=np.float32))[0])
    device = replay.unwrapped.device  # type: ignore[attr-defined]
    replay.close()
    assert len(device) == len(live) == 302
    for a, b in zip(live, replayed, strict=True):
        np.testing.assert_array_equal(a, b)
    # the replayed force display is what the live host sent (to the 1 mN m of the wire)
    sent = np.array([encode_torque(t, 1, 0)[1] for t in device.feedback])
    np.testing.assert_allclose(sent, device.recorded_torques, atol=5e-4 + 1e-12)
    assert np.abs(device.recorded_torques).max() > 0.01  # the pen was felt


def test_replay_refuses_logs_without_host_cycles(tmp_path: Path) -> None:
    log = tmp_path / "only_rx.asc"
    with can.Logger(str(log)) as logger:
        for f in encode_sensors(np.zeros(10), 0):
            logger(can.Message(arbitration_id=f.arbitration_id, data=f.data, is_extended_id=False))
    with pytest.raises(ReplayError, match="no host cycles"):
        ReplayGlove(log)


def test_profile_kwarg_sets_person_and_calibration(channel: str, tmp_path: Path) -> None:
    from ias_gym.envs.glove_grasp import default_calibration
    from ias_gym.glove.calibration import evaluate
    from ias_gym.glove.hand import PersonParams
    from ias_gym.glove.profile import DEFAULT_GLOVE_ID, Profile, ProfileError, save_profile
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


def test_glove_bench_prints_its_statistics_as_json(
    channel: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(
        ["glove-bench", "--rate", "500", "--seconds", "0.4", "--channel", channel, "--json"]
    )
    assert code == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    keys = {"rate_hz", "period_median_ms", "period_p99_ms", "period_max_ms"}
    keys |= {"overrun_fraction", "frames_dropped", "watchdog_trips"}
    assert keys <= set(result)
    assert result["cycles"] == 199 and result["watchdog_trips"] == 0
    assert 0 < result["period_median_ms"] <= result["period_p99_ms"] <= result["period_max_ms"]


def test_a_can_glove_session_is_recorded_as_a_skill(channel: str, tmp_path: Path) -> None:
    from ias_gym.skills import SkillDB
    from ias_gym.skills.record import record_skills

    db = tmp_path / "skills.db"
    with GloveEmulator(channel=channel, rate_hz=500):
        (skill_id,) = record_skills(
            "IAS-GloveHardware-v0",
            "teleop",
            1,
            db,
            progress=False,
            env_kwargs={"channel": channel, "control_dt": 0.004, "duration": 1.2},
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


def test_glove_emulator_command_runs_and_reports(
    channel: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["glove-emulator", "--channel", channel, "--rate", "500", "--seconds", "0.2"])
    out = capsys.readouterr().out
    assert code == 0 and "Ctrl-C stops" in out
    sent = int(out.split("sent ")[1].split(" samples")[0])
    assert 50 <= sent <= 110  # 500 Hz for 0.2 s


def test_glove_bench_refuses_a_process_emulator_on_the_virtual_bus(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["glove-bench", "--emulator", "process", "--seconds", "0.1"]) == 2
    assert "does not leave the process" in capsys.readouterr().err

"""Recording a glove session to a python-can log and replaying it (python-can's virtual bus):
the same observations bit for bit, and one clear error for a file that is not a recording."""

from __future__ import annotations

from pathlib import Path

import can
import gymnasium as gym
import numpy as np
import pytest

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.errors import InputError
from ias_gym.hardware import GloveEmulator, ReplayError, ReplayGlove
from ias_gym.hardware.protocol import encode_sensors, encode_torque

#: Watchdogs of the recording tests [s]: they test record and replay, not the 20 ms watchdog
#: (tests/test_can_glove.py does), and the interpreter can stall longer late in the suite.
SLACK = 0.2

pytestmark = [
    pytest.mark.realtime,
    pytest.mark.filterwarnings("error"),
    pytest.mark.usefixtures("no_python_can_warnings", "no_gc_pauses"),
]


@pytest.mark.parametrize("suffix", [".asc", ".blf", ".log"])
def test_recorded_session_replays_to_identical_observations(
    channel: str, tmp_path: Path, suffix: str
) -> None:
    log = tmp_path / f"session{suffix}"
    live: list[np.ndarray] = []
    with GloveEmulator(channel=channel, rate_hz=500, watchdog_timeout=SLACK):
        env = gym.make(
            "IAS-GloveHardware-v0",
            channel=channel,
            record=log,
            control_dt=0.004,
            watchdog_timeout=SLACK,
        )
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


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """One short recorded session per log format."""
    out = {}
    for k, suffix in enumerate((".asc", ".blf", ".log")):
        log = tmp_path_factory.mktemp("rec") / f"session{suffix}"
        channel = f"ias-replay-rec-{k}"
        with GloveEmulator(channel=channel, rate_hz=500, watchdog_timeout=SLACK):
            env = gym.make(
                "IAS-GloveHardware-v0",
                channel=channel,
                record=log,
                control_dt=0.004,
                watchdog_timeout=SLACK,
            )
            env.reset(seed=0)
            for _ in range(60):
                env.step(np.zeros(10, dtype=np.float32))
            env.close()
        assert len(ReplayGlove(log)) == 61
        out[suffix] = log
    return out


@pytest.mark.parametrize("suffix", [".asc", ".blf", ".log"])
@pytest.mark.parametrize("keep", [0.5, 0.97])
def test_a_truncated_recording_is_refused(
    recordings: dict[str, Path], tmp_path: Path, suffix: str, keep: float
) -> None:
    """A session cut short (a crash, a partial copy) is not replayed as if it were whole:
    python-can's readers stop early without a word on most cuts; every recording ends with
    the host's Disable, so its absence tells. A cut into a .blf's tail (its last compressed
    container and padding) can leave every frame readable; then the whole session must
    replay, never a part of it."""
    data = recordings[suffix].read_bytes()
    cut = tmp_path / f"cut{suffix}"
    cut.write_bytes(data[: int(len(data) * keep)])
    if keep < 0.9 or suffix != ".blf":
        with pytest.raises(ReplayError, match=r"cut\.(asc|blf|log)") as info:
            ReplayGlove(cut)
        assert "truncated" in str(info.value) or "not a readable" in str(info.value)
        return
    try:
        replay = ReplayGlove(cut)
    except ReplayError as exc:
        assert "truncated" in str(exc) or "not a readable" in str(exc)
    else:
        assert len(replay) == 61, "a partial recording was replayed as a session"


@pytest.mark.parametrize(
    ("name", "content", "match"),
    [
        ("empty.blf", b"", "is empty"),
        ("empty.asc", b"", "is empty"),
        ("noise.blf", bytes(range(256)) * 4, "not a readable python-can .blf log"),
        ("text.log", b"this is not a CAN log\n", "not a readable python-can .log log"),
        ("text.asc", b"hello\nworld\n", "no host cycles"),
        ("session.csv", b"timestamp,arbitration_id\n", r"\.asc, \.blf, \.log"),
    ],
)
def test_a_file_that_is_not_a_recording_is_one_input_error(
    tmp_path: Path, name: str, content: bytes, match: str
) -> None:
    """Each of python-can's readers fails its own way on a foreign file (``struct.error``,
    ``BLFParseError``, ``ValueError: not enough values to unpack``, ...); the env answers
    with one InputError naming the file, made through ``gym.make(replay=...)``."""
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(InputError, match=match) as info:
        gym.make("IAS-GloveHardware-v0", replay=path)
    assert name in str(info.value)


def test_a_missing_replay_file_is_an_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"gone\.blf.*no such file"):
        ReplayGlove(tmp_path / "gone.blf")

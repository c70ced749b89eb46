"""The glove's CAN protocol without a bus: the DBC, byte fixtures, the compiled codec against
cantools, range checks both ways, the frame receiver, the bus load."""

from __future__ import annotations

from dataclasses import astuple

import cantools
import numpy as np
import pytest

from ias_gym.glove.device import ACTUATED_JOINTS, MAX_FEEDBACK_TORQUE
from ias_gym.glove.hand import SENSOR_NAMES
from ias_gym.hardware import DBC_PATH, FrameReceiver, Sample, bus_load, database
from ias_gym.hardware.protocol import (
    SENSORS_A,
    SENSORS_B,
    TORQUE_COMMAND,
    ProtocolError,
    UnknownIdError,
    decode_frame,
    encode_frame,
    encode_sensors,
    encode_torque,
    frame_id,
    in_sensor_range,
    layout,
)

pytestmark = pytest.mark.filterwarnings("error")


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


def _random_values(msg: cantools.database.can.Message, rng: np.random.Generator) -> dict:
    """Values across each signal's whole range, its two limits included now and then."""
    values: dict[str, float] = {}
    for s in msg.signals:
        pick = rng.integers(4)
        if pick == 0:
            values[s.name] = s.minimum
        elif pick == 1:
            values[s.name] = s.maximum
        elif s.scale != 1:
            values[s.name] = float(rng.uniform(s.minimum, s.maximum))
        else:
            values[s.name] = int(rng.integers(s.minimum, s.maximum + 1))
    return values


@pytest.mark.parametrize("seed", range(3))
def test_compiled_codec_writes_and_reads_cantools_bytes(seed: int) -> None:
    """The fast codec of the 1 kHz loop packs exactly cantools' bytes (its rounding, two's
    complement for the signed torques, bit positions) and reads them back as cantools does."""
    rng = np.random.default_rng(seed)
    for msg in database().messages:
        for _ in range(200):
            values = _random_values(msg, rng)
            reference = bytes(msg.encode(values, strict=True))
            assert encode_frame(msg.name, values) == reference, (msg.name, values)
            theirs = msg.decode(reference, decode_choices=False)
            ours = decode_frame(msg.frame_id, reference).values
            assert ours.keys() == theirs.keys()
            for name, value in theirs.items():
                assert ours[name] == pytest.approx(value, abs=1e-12), (msg.name, name)


def test_compiled_codec_refuses_values_outside_the_dbc_range() -> None:
    """Nothing outside the DBC's range reaches the wire through the codec (cantools'
    ``strict=True`` did this before), and a raw value past a limit is refused on decoding."""
    values = {**dict.fromkeys(ACTUATED_JOINTS, 0.0), "Counter": 0, "SampleCounter": 0}
    with pytest.raises(ProtocolError, match=r"index_mcp = 0\.6 outside"):
        encode_frame(TORQUE_COMMAND, {**values, "index_mcp": 0.6})
    with pytest.raises(ProtocolError, match="Counter = 16 outside"):
        encode_frame(TORQUE_COMMAND, {**values, "Counter": 16})  # a 4-bit field: 16 wraps
    with pytest.raises(ProtocolError, match="thumb_flexion"):
        encode_frame(TORQUE_COMMAND, {**values, "thumb_flexion": -0.51})
    # raw -512, the 10-bit field's most negative value: in the field, out of the range
    raw = bytearray(encode_frame(TORQUE_COMMAND, values))
    raw[0], raw[1] = 0x00, raw[1] | 0x02
    with pytest.raises(ProtocolError, match="index_mcp"):
        decode_frame(frame_id(TORQUE_COMMAND), bytes(raw))
    assert [s.name for s in layout(TORQUE_COMMAND).signals][:5] == list(ACTUATED_JOINTS)

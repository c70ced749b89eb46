"""The glove's CAN protocol (``ias_glove.dbc``): pure encode / decode, no bus.

Messages (ids, DLC; layouts and scaling in the DBC):

- ``GloveSensorsA`` (0x110, 8 B) and ``GloveSensorsB`` (0x111, 8 B), glove -> host, one of
  each per sample: an 8-bit rolling ``Counter`` (the same in both: it pairs them) and five
  of the 10 readings Ψ each, 11 bits, 2 mrad, range [-1.6, 2.4] rad.
- ``GloveSensorsFD`` (0x112, 24 B, CAN FD only): all 10 readings at 0.1 mrad and the counter.
- ``TorqueCommand`` (0x100, 8 B), host -> glove, one per host cycle: the torques of the 5
  actuated joints (10 bits, 1 mN m, range [-0.5, 0.5] N m = the actuators' limits), a 4-bit
  rolling ``Counter`` (+1 per host cycle; a repeat of the last counter marks a safety command
  carrying zero torque) and ``SampleCounter``, the counter of the sensor sample the torques
  were computed from (latency, and the replay of recorded sessions).
- ``HostCommand`` (0x080, 1 B), host -> glove: ``Enable``, ``ClearFaults``.
- ``GloveStatus`` (0x090, 1 B), glove -> host, 50 Hz: ``TorqueEnabled`` and latched faults.

The DBC is read with cantools; the frames of the 1 kHz loop are packed and unpacked by
:class:`Layout`, a codec compiled once from the DBC (the messages are little-endian signals
in one integer: decoding a sensor frame takes 3 us where cantools took 8, encoding a
sample's two frames 20 us where it took 35, on the host loop's and the emulator's time). It
rounds as cantools does, so the bytes are the same (tested against cantools), and it
range-checks both ways: :func:`encode_frame` refuses a value outside its DBC range, and
:func:`decode_frame` (cantools does not check ranges when it decodes) raises
:class:`ProtocolError` for a frame with a wrong length, an unknown id or any value outside
its range (the caller counts and drops it).
"""

from __future__ import annotations

import functools
import importlib.resources
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ias_gym.errors import IasGymError, ProtocolError, UnknownIdError  # noqa: F401 - defined there, raised here
from ias_gym.glove.device import ACTUATED_JOINTS
from ias_gym.glove.hand import SENSOR_NAMES

if TYPE_CHECKING:
    import cantools.database

#: The protocol's DBC file, shipped in the package.
DBC_PATH = Path(str(importlib.resources.files("ias_gym.hardware") / "ias_glove.dbc"))

HOST_COMMAND = "HostCommand"
GLOVE_STATUS = "GloveStatus"
TORQUE_COMMAND = "TorqueCommand"
SENSORS_A = "GloveSensorsA"
SENSORS_B = "GloveSensorsB"
SENSORS_FD = "GloveSensorsFD"
#: Sensor messages of a sample: classic CAN (two frames) and CAN FD (one frame).
CLASSIC_SENSOR_MESSAGES = (SENSORS_A, SENSORS_B)
FD_SENSOR_MESSAGES = (SENSORS_FD,)
#: Bit rates [bit/s]: classic CAN (and the FD arbitration phase), the FD data phase.
BITRATE = 1_000_000
FD_DATA_BITRATE = 5_000_000


def _require_cantools() -> Any:
    try:
        import cantools
    except ImportError as e:  # pragma: no cover - exercised without the extra
        raise ImportError(
            "the glove's CAN protocol needs cantools and python-can: "
            "pip install 'ias-gym[hardware]'"
        ) from e
    return cantools


@functools.cache
def database() -> cantools.database.can.Database:
    """The protocol as a cantools database (loaded once, strict)."""
    cantools = _require_cantools()
    return cantools.database.load_file(str(DBC_PATH), strict=True)


@dataclass(frozen=True)
class Frame:
    """A frame to send: arbitration id, payload, CAN FD or not."""

    arbitration_id: int
    data: bytes
    is_fd: bool = False


@dataclass(frozen=True)
class Decoded:
    """A decoded, range-checked frame: the message name and its physical signal values."""

    name: str
    values: dict[str, float]


@functools.cache
def _ranges(name: str) -> tuple[tuple[str, float, float], ...]:
    return tuple((s.name, s.minimum, s.maximum) for s in layout(name).signals)


@functools.cache
def _by_id() -> dict[int, Layout]:
    return {int(m.frame_id): layout(m.name) for m in database().messages}


def frame_id(name: str) -> int:
    """Arbitration id of message ``name``."""
    return int(_message(name).frame_id)


def limits(name: str, signal: str) -> tuple[float, float]:
    """(minimum, maximum) of a signal in the DBC (physical units)."""
    for s, lo, hi in _ranges(name):
        if s == signal:
            return lo, hi
    raise KeyError(f"message {name} has no signal {signal!r}")


def decode_frame(arbitration_id: int, data: bytes | bytearray) -> Decoded:
    """Decode and range-check one frame.

    Raises:
        UnknownIdError: an id the protocol does not have.
        ProtocolError: a length other than the DBC's, or a value outside its range (the
            message says which).
    """
    layout = _by_id().get(arbitration_id)
    if layout is None:
        raise UnknownIdError(f"unknown arbitration id 0x{arbitration_id:X}")
    return Decoded(layout.name, layout.decode(data))


@dataclass(frozen=True)
class _Signal:
    """One signal's place in its message's integer and its scaling (from the DBC)."""

    name: str
    start: int  # least significant bit, little-endian bit numbering
    mask: int  # (1 << length) - 1
    sign_bit: int  # 1 << (length - 1) for signed signals, 0 for unsigned
    scale: float
    offset: float
    minimum: float
    maximum: float
    raw_minimum: int
    raw_maximum: int
    to_raw: Any  # cantools' scaled -> raw conversion (its rounding: the same bytes)


class Layout:
    """A message's codec compiled from the DBC: every signal is a little-endian bit field of
    one integer (``int.from_bytes(data, "little")``), scaled linearly.

    Args:
        message: the cantools message.

    Raises:
        ProtocolError: a signal this codec cannot pack (big-endian, float, multiplexed, or
            without a [min|max] range); the DBC shipped with the package has none.
    """

    def __init__(self, message: Any) -> None:
        self.name = str(message.name)
        self.frame_id = int(message.frame_id)
        self.length = int(message.length)
        if message.is_multiplexed():
            raise ProtocolError(f"{self.name}: multiplexed messages are not supported")
        signals = []
        for s in message.signals:
            where = f"{self.name}.{s.name} in {DBC_PATH}"
            if s.byte_order != "little_endian" or s.is_float:
                raise ProtocolError(f"{where}: only little-endian integer signals are supported")
            if s.minimum is None or s.maximum is None:  # the device layer checks every range
                raise ProtocolError(f"{where} has no [min|max]")
            lo, hi = float(s.minimum), float(s.maximum)
            raw_lo, raw_hi = sorted(
                (s.conversion.numeric_scaled_to_raw(lo), s.conversion.numeric_scaled_to_raw(hi))
            )
            signals.append(
                _Signal(
                    name=str(s.name),
                    start=int(s.start),
                    mask=(1 << s.length) - 1,
                    sign_bit=(1 << (s.length - 1)) if s.is_signed else 0,
                    scale=float(s.scale),
                    offset=float(s.offset),
                    minimum=lo,
                    maximum=hi,
                    raw_minimum=int(raw_lo),
                    raw_maximum=int(raw_hi),
                    to_raw=s.conversion.numeric_scaled_to_raw,
                )
            )
        self.signals = tuple(signals)

    def encode(self, values: Mapping[str, float]) -> bytes:
        """The payload for physical ``values`` (one per signal).

        Raises:
            ProtocolError: a value outside its DBC range (nothing is packed).
            KeyError: a signal without a value.
        """
        word = 0
        for s in self.signals:
            raw = s.to_raw(values[s.name])
            if not s.raw_minimum <= raw <= s.raw_maximum:
                raise ProtocolError(
                    f"{self.name}.{s.name} = {values[s.name]} outside [{s.minimum}, {s.maximum}]"
                )
            word |= (raw & s.mask) << s.start
        return word.to_bytes(self.length, "little")

    def decode(self, data: bytes | bytearray) -> dict[str, float]:
        """Physical values of a payload, range-checked.

        Raises:
            ProtocolError: a length other than the DBC's, or a value outside its range.
        """
        if len(data) != self.length:
            raise ProtocolError(
                f"{self.name}: {len(data)} data bytes, the protocol has {self.length}"
            )
        word = int.from_bytes(data, "little")
        values = {}
        for s in self.signals:
            raw = (word >> s.start) & s.mask
            if raw & s.sign_bit:
                raw -= s.mask + 1
            # the range is checked on the raw integer: no float rounding at the limits
            if not s.raw_minimum <= raw <= s.raw_maximum:
                value = raw * s.scale + s.offset
                raise ProtocolError(
                    f"{self.name}.{s.name} = {value} outside [{s.minimum}, {s.maximum}]"
                )
            values[s.name] = float(raw * s.scale + s.offset)
        return values


@functools.cache
def layout(name: str) -> Layout:
    """The compiled codec of message ``name``."""
    return Layout(_message(name))


@functools.cache
def _message(name: str) -> Any:
    return database().get_message_by_name(name)


def encode_frame(name: str, values: Mapping[str, float]) -> bytes:
    """The payload of message ``name`` for physical ``values`` (cantools' bytes), with every
    raw value on the wire inside its DBC range.

    Raises:
        ProtocolError: a value outside its DBC range.
    """
    return layout(name).encode(values)


def sensor_messages(fd: bool) -> tuple[str, ...]:
    """Names of the sensor messages of one sample (classic: A and B; FD: one frame)."""
    return FD_SENSOR_MESSAGES if fd else CLASSIC_SENSOR_MESSAGES


def encode_sensors(psi: ArrayLike, counter: int, *, fd: bool = False) -> list[Frame]:
    """The frames of one sample: readings Ψ ``(10,)`` [rad] saturated at the DBC's range
    (as the glove's converters saturate), the 8-bit ``counter``.

    Raises:
        ValueError: wrong shape or NaN (a glove never sends NaN; the emulator must not).
    """
    p = np.asarray(psi, dtype=np.float64)
    if p.shape != (len(SENSOR_NAMES),) or not np.isfinite(p).all():
        raise ValueError(f"readings must be 10 finite values [rad], got {p.tolist()}")
    readings = p.tolist()  # plain floats: cheaper than numpy for 10 values, every sample
    frames = []
    for name in sensor_messages(fd):
        values: dict[str, float] = {"Counter": counter % 256}
        for signal, i, lo, hi in _sensor_fields(name):
            values[signal] = min(max(readings[i], lo), hi)
        frames.append(Frame(frame_id(name), encode_frame(name, values), fd))
    return frames


def in_sensor_range(psi: ArrayLike, *, fd: bool = False) -> bool:
    """Whether every reading Ψ [rad] lies in its DBC range (else :func:`encode_sensors`
    saturates it, as the glove's converters do)."""
    readings = np.asarray(psi, dtype=np.float64).tolist()
    return all(
        lo <= readings[i] <= hi
        for name in sensor_messages(fd)
        for _, i, lo, hi in _sensor_fields(name)
    )


@functools.cache
def _sensor_fields(name: str) -> tuple[tuple[str, int, float, float], ...]:
    """(signal, index into Ψ, low [rad], high [rad]) of a sensor message's readings."""
    return tuple(
        (s, SENSOR_NAMES.index(s), lo, hi) for s, lo, hi in _ranges(name) if s != "Counter"
    )


@functools.cache
def _torque_limits() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    lo = np.array([limits(TORQUE_COMMAND, j)[0] for j in ACTUATED_JOINTS])
    hi = np.array([limits(TORQUE_COMMAND, j)[1] for j in ACTUATED_JOINTS])
    return lo, hi


def clamp_torques(torques: ArrayLike) -> NDArray[np.float64]:
    """Torques [N m] for :data:`ACTUATED_JOINTS` made safe to send: NaN or inf -> 0, then
    clamped to the DBC's ranges (the actuators' limits).

    Raises:
        ValueError: wrong shape.
    """
    t = np.array(torques, dtype=np.float64)
    if t.shape != (len(ACTUATED_JOINTS),):
        raise ValueError(f"torques must have shape ({len(ACTUATED_JOINTS)},), got {t.shape}")
    t[~np.isfinite(t)] = 0.0
    return np.clip(t, *_torque_limits())


def encode_torque(
    torques: ArrayLike, counter: int, sample_counter: int, *, fd: bool = False
) -> tuple[Frame, NDArray[np.float64]]:
    """A ``TorqueCommand`` frame and the torques it carries (after :func:`clamp_torques`).

    Args:
        torques: ``(5,)`` [N m] in :data:`ACTUATED_JOINTS` order.
        counter: 4-bit command counter.
        sample_counter: counter of the sensor sample the torques come from.
        fd: send as a CAN FD frame (bit-rate switch).
    """
    t = clamp_torques(torques)
    values = dict(zip(ACTUATED_JOINTS, t.tolist(), strict=True))
    values["Counter"] = counter % 16
    values["SampleCounter"] = sample_counter % 256
    return Frame(frame_id(TORQUE_COMMAND), encode_frame(TORQUE_COMMAND, values), fd), t


def torques_of(decoded: Decoded) -> NDArray[np.float64]:
    """The ``(5,)`` torques [N m] of a decoded ``TorqueCommand``."""
    return np.array([decoded.values[j] for j in ACTUATED_JOINTS])


def readings_of(decoded: Decoded) -> dict[int, float]:
    """{index into Ψ: reading [rad]} of a decoded sensor frame."""
    return {SENSOR_NAMES.index(k): v for k, v in decoded.values.items() if k != "Counter"}


def encode_host_command(enable: bool, clear_faults: bool, counter: int) -> Frame:
    """A ``HostCommand`` frame."""
    values = {"Enable": int(enable), "ClearFaults": int(clear_faults), "Counter": counter % 16}
    return Frame(frame_id(HOST_COMMAND), encode_frame(HOST_COMMAND, values))


def encode_status(
    enabled: bool, watchdog: bool, command_fault: bool, sensor_fault: bool, counter: int
) -> Frame:
    """A ``GloveStatus`` frame."""
    values = {
        "TorqueEnabled": int(enabled),
        "FaultWatchdog": int(watchdog),
        "FaultCommand": int(command_fault),
        "FaultSensor": int(sensor_fault),
        "Counter": counter % 16,
    }
    return Frame(frame_id(GLOVE_STATUS), encode_frame(GLOVE_STATUS, values))


# --------------------------------------------------------------------------- bus load
def frame_time(n_bytes: int, *, fd: bool = False, worst_case: bool = True) -> float:
    """Time one data frame with an 11-bit id occupies the bus [s], including the 3-bit
    interframe space.

    Classic CAN at :data:`BITRATE`: 47 + 8n bits, plus up to ``(34 + 8n - 1) // 4`` stuff
    bits (ISO 11898-1) when ``worst_case``. CAN FD with bit-rate switch: arbitration and
    end of frame (29 bits, + 4 stuff bits) at :data:`BITRATE`, ESI, DLC, data, stuff count,
    CRC (17 bits up to 16 bytes, else 21) with its fixed stuff bits and delimiter at
    :data:`FD_DATA_BITRATE`, plus dynamic stuff bits over ESI..data when ``worst_case``.
    """
    if not fd:
        bits = 47 + 8 * n_bytes + ((34 + 8 * n_bytes - 1) // 4 if worst_case else 0)
        return bits / BITRATE
    crc = 17 if n_bytes <= 16 else 21
    nominal = 17 + 12 + (4 if worst_case else 0)
    data = 5 + 8 * n_bytes + 4 + crc + math.ceil((crc + 4) / 4) + 1
    if worst_case:
        data += (5 + 8 * n_bytes - 1) // 4
    return nominal / BITRATE + data / FD_DATA_BITRATE


def bus_load(rate_hz: float, *, fd: bool = False, worst_case: bool = True) -> dict[str, float]:
    """Bus load of the protocol at sample rate ``rate_hz`` [Hz]: per message its frames/s and
    share of the bus, and ``"total"`` (fraction of the bus time, 1 = saturated).

    Per sample: the sensor frames and one ``TorqueCommand``; ``GloveStatus`` at its DBC cycle
    time (``HostCommand`` is sent on change only and left out).
    """
    db = database()
    rows: dict[str, float] = {}
    per_sample = [*sensor_messages(fd), TORQUE_COMMAND]
    for name in per_sample:
        msg = db.get_message_by_name(name)
        rows[name] = rate_hz * frame_time(msg.length, fd=fd, worst_case=worst_case)
    status = db.get_message_by_name(GLOVE_STATUS)
    if status.cycle_time is None:
        raise ProtocolError(f"{GLOVE_STATUS} has no GenMsgCycleTime in {DBC_PATH}")
    rows[GLOVE_STATUS] = (1000.0 / status.cycle_time) * frame_time(
        status.length, worst_case=worst_case
    )
    rows["total"] = sum(rows.values())
    return rows

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

cantools encodes with range checks (``strict=True``) but does not check ranges when it
decodes, so :func:`decode_frame` does: a frame with a wrong length, an unknown id or any
value outside its DBC range raises :class:`ProtocolError` (the caller counts and drops it).
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

from ias_gym.errors import IasGymError
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


class ProtocolError(IasGymError, ValueError):
    """A frame that does not fit the protocol (unknown id, wrong length, value out of range)."""


class UnknownIdError(ProtocolError):
    """A frame whose id is not in the protocol: another node's traffic, not a fault."""


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
    rows = []
    for s in _message(name).signals:
        if s.minimum is None or s.maximum is None:  # the device layer checks every range
            raise ProtocolError(f"{name}.{s.name} has no [min|max] in {DBC_PATH}")
        rows.append((s.name, float(s.minimum), float(s.maximum)))
    return tuple(rows)


@functools.cache
def _by_id() -> dict[int, Any]:
    return {m.frame_id: m for m in database().messages}


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
    msg = _by_id().get(arbitration_id)
    if msg is None:
        raise UnknownIdError(f"unknown arbitration id 0x{arbitration_id:X}")
    if len(data) != msg.length:
        raise ProtocolError(f"{msg.name}: {len(data)} data bytes, the protocol has {msg.length}")
    values = msg.decode(bytes(data), decode_choices=False, scaling=True)
    for signal, lo, hi in _ranges(msg.name):
        v = values[signal]
        # slack for the float rounding of raw * scale + offset
        if not lo - 1e-9 <= v <= hi + 1e-9:
            raise ProtocolError(f"{msg.name}.{signal} = {v} outside [{lo}, {hi}]")
    return Decoded(msg.name, {k: float(v) for k, v in values.items()})


@functools.cache
def _message(name: str) -> Any:
    return database().get_message_by_name(name)


def _encode(name: str, values: Mapping[str, float], strict: bool = True) -> bytes:
    return bytes(_message(name).encode(values, strict=strict))


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
    frames = []
    for name in sensor_messages(fd):
        index, lo, hi = _sensor_layout(name)
        values = dict(zip(_reading_signals(name), np.clip(p[index], lo, hi).tolist(), strict=True))
        values["Counter"] = counter % 256
        # In range by construction (clipped): cantools' check would only cost time.
        frames.append(Frame(frame_id(name), _encode(name, values, strict=False), fd))
    return frames


def in_sensor_range(psi: ArrayLike, *, fd: bool = False) -> bool:
    """Whether every reading Ψ [rad] lies in its DBC range (else :func:`encode_sensors`
    saturates it, as the glove's converters do)."""
    p = np.asarray(psi, dtype=np.float64)
    for name in sensor_messages(fd):
        index, lo, hi = _sensor_layout(name)
        if np.any(p[index] < lo) or np.any(p[index] > hi):
            return False
    return True


@functools.cache
def _reading_signals(name: str) -> tuple[str, ...]:
    return tuple(s for s, _, _ in _ranges(name) if s != "Counter")


@functools.cache
def _sensor_layout(name: str) -> tuple[NDArray[np.intp], NDArray[np.float64], NDArray[np.float64]]:
    """Indices into Ψ of a sensor message's readings, and their (low, high) [rad]."""
    rows = [(SENSOR_NAMES.index(s), lo, hi) for s, lo, hi in _ranges(name) if s != "Counter"]
    index, lo, hi = zip(*rows, strict=True)
    return np.array(index), np.array(lo), np.array(hi)


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
    return Frame(frame_id(TORQUE_COMMAND), _encode(TORQUE_COMMAND, values), fd), t


def torques_of(decoded: Decoded) -> NDArray[np.float64]:
    """The ``(5,)`` torques [N m] of a decoded ``TorqueCommand``."""
    return np.array([decoded.values[j] for j in ACTUATED_JOINTS])


def readings_of(decoded: Decoded) -> dict[int, float]:
    """{index into Ψ: reading [rad]} of a decoded sensor frame."""
    return {SENSOR_NAMES.index(k): v for k, v in decoded.values.items() if k != "Counter"}


def encode_host_command(enable: bool, clear_faults: bool, counter: int) -> Frame:
    """A ``HostCommand`` frame."""
    values = {"Enable": int(enable), "ClearFaults": int(clear_faults), "Counter": counter % 16}
    return Frame(frame_id(HOST_COMMAND), _encode(HOST_COMMAND, values))


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
    return Frame(frame_id(GLOVE_STATUS), _encode(GLOVE_STATUS, values))


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

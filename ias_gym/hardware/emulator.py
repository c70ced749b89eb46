"""A glove on the bus without the glove: the protocol spoken by a simulated person.

:class:`GloveEmulator` is the device side of ``ias_glove.dbc`` with a simulated glove
behind it (the sensor model of :class:`~ias_gym.glove.device.SimulatedGlove` on a person
running a scripted operator): every ``1 / rate_hz`` it sends one
sample's sensor frames; it applies the ``TorqueCommand`` torques while enabled
(``HostCommand`` Enable), and enforces the device-side watchdog: no valid command for
``watchdog_timeout`` [s] while enabled -> torque off and ``FaultWatchdog`` latched until the
next Enable. It reports ``GloveStatus`` every 20 ms. :class:`FaultInjection` makes it a
bad glove (dropped, corrupted, wrong-length and garbage frames, error frames) and
:meth:`GloveEmulator.pause` a silent one, for the host's tests.

Run it in a second process with ``ias-gym glove-emulator --interface ... --channel ...``.
"""

from __future__ import annotations

import collections
import dataclasses
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ias_gym.errors import InputError
from ias_gym.glove.device import ACTUATED_JOINTS
from ias_gym.glove.hand import PersonParams
from ias_gym.glove.ids import check_id
from ias_gym.glove.profile import DEFAULT_GLOVE_ID
from ias_gym.glove.sensor_model import sensor_readings
from ias_gym.hardware.can_glove import SEND_TIMEOUT, open_bus, require_can, to_message
from ias_gym.hardware.protocol import (
    BITRATE,
    HOST_COMMAND,
    TORQUE_COMMAND,
    Frame,
    ProtocolError,
    UnknownIdError,
    decode_frame,
    encode_sensors,
    encode_status,
    in_sensor_range,
    torques_of,
)

if TYPE_CHECKING:
    import can

STATUS_PERIOD = 0.02  # GloveStatus cycle time [s] (the DBC's GenMsgCycleTime)


@dataclass(frozen=True)
class FaultInjection:
    """How badly the emulated glove behaves (probabilities per sensor frame, or per sample for
    error frames; drawn from ``seed``).

    Attributes:
        drop: a sensor frame is not sent.
        corrupt: a sensor frame is sent with 1-3 random bits flipped.
        wrong_length: a sensor frame is sent one byte short or long.
        garbage: after a sample, a frame of random bytes on a random protocol id.
        error_frame: after a sample, a CAN error frame.
        seed: seeds the draws.
    """

    drop: float = 0.0
    corrupt: float = 0.0
    wrong_length: float = 0.0
    garbage: float = 0.0
    error_frame: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name != "seed" and not 0.0 <= v <= 1.0:
                raise ValueError(f"FaultInjection.{f.name} must be a probability, got {v}")


@dataclass
class EmulatorStats:
    """What the emulated glove did and saw.

    Attributes:
        samples: samples produced; frames_sent: frames put on the bus (incl. injected faults).
        injected: injected faults by kind (drop, corrupt, wrong_length, garbage, error_frame).
        commands: valid torque commands applied; commands_rejected: protocol frames from the
            host that failed the checks (length, range); commands_lost: gaps in the command
            counter; safety_commands: zero-torque repeats (watchdog, close).
        watchdog_trips: device-side watchdog trips; late_cycles: cycles started a full period
            or more late (the emulator's own overruns); tx_errors: frames the bus refused
            (a receiver's queue full).
    """

    samples: int = 0
    frames_sent: int = 0
    injected: dict[str, int] = dataclasses.field(default_factory=dict)
    commands: int = 0
    commands_rejected: int = 0
    commands_lost: int = 0
    safety_commands: int = 0
    watchdog_trips: int = 0
    late_cycles: int = 0
    tx_errors: int = 0


class GloveEmulator:
    """The glove's side of the protocol on a python-can bus, a simulated person wearing it.

    Args:
        interface, channel: the bus (``can.Bus(interface=..., channel=...)``).
        person: the wearer (default: ``PersonParams.sample("p1")``).
        operator: ``(person) -> Θ(t)``, the scripted operator (default: the pen pinch of
            IAS-GloveGrasp-v0 from its pre-shape). The script restarts at every Enable.
        seed: seeds the sensor noise.
        rate_hz: sample rate [Hz].
        fd: send the CAN FD sensor frame instead of the two classic ones.
        watchdog_timeout: device-side watchdog [s].
        faults: fault injection (default: a good glove).
        glove_id: the emulated glove's id.
        **bus_kwargs: passed to ``can.Bus``.

    Raises:
        InputError: a non-positive ``rate_hz`` or ``watchdog_timeout``; (:meth:`start`) a
            bus that cannot be opened.
    """

    def __init__(
        self,
        interface: str = "virtual",
        channel: str | int = "ias-glove",
        *,
        person: PersonParams | None = None,
        operator: Callable[[PersonParams], Callable[[float], NDArray[np.float64]]] | None = None,
        seed: int = 0,
        rate_hz: float = 1000.0,
        fd: bool = False,
        watchdog_timeout: float = 0.02,
        faults: FaultInjection | None = None,
        glove_id: str = DEFAULT_GLOVE_ID,
        **bus_kwargs: Any,
    ) -> None:
        for name, value in (("rate_hz", rate_hz), ("watchdog_timeout", watchdog_timeout)):
            if not 0 < value < float("inf"):
                raise InputError(f"{name} must be a positive number, got {value}")
        self.interface, self.channel = interface, channel
        self.person = person if person is not None else PersonParams.sample("p1")
        if operator is None:
            from ias_gym.glove.operator import FromPreShape
            from ias_gym.sim.glove_scene import scene_operator

            def operator(p: PersonParams) -> Callable[[float], NDArray[np.float64]]:
                return FromPreShape(scene_operator(p))

        #: Θ(t) [rad] of the wearer; a pure function of t, built once (building the pen
        #: pinch solves the person's inverse kinematics: ~0.1 s the glove must not go quiet).
        self._operator = operator(self.person)
        self.seed = seed
        self.rate_hz = float(rate_hz)
        self.fd = bool(fd)
        self.watchdog_timeout = float(watchdog_timeout)
        self.faults = faults if faults is not None else FaultInjection()
        self.glove_id = check_id(glove_id, "glove_id")
        self._bus_kwargs = {"bitrate": BITRATE, **bus_kwargs}
        if fd:
            self._bus_kwargs.setdefault("fd", True)
        self._rng = np.random.default_rng(self.faults.seed)
        self._faulty = any(getattr(self.faults, k) > 0 for k in _FAULT_KINDS)
        self._protocol_frames = _protocol_frames()
        self.stats = EmulatorStats(injected=dict.fromkeys(_FAULT_KINDS, 0))
        self._lock = threading.Lock()
        self._bus: Any = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._pause_until = 0.0
        self._enabled = False
        self._torque = np.zeros(len(ACTUATED_JOINTS))
        self._fault_watchdog = self._fault_command = self._fault_sensor = False
        self._last_command_time = 0.0
        self._last_cmd_counter: int | None = None
        self._counter = 0
        self._status_counter = 0
        self._restarts = 0
        self._restart_person()
        #: (time [s], torques [N m]) applied, one per accepted command (last 100 000).
        self.applied: collections.deque[tuple[float, NDArray[np.float64]]] = collections.deque(
            maxlen=100_000
        )
        #: How many samples old the host's commands were (echoed counter), last 100 000.
        self.command_age: collections.deque[int] = collections.deque(maxlen=100_000)

    def _restart_person(self) -> None:
        """The person starts the script afresh (at every Enable): clock 0, new noise."""
        self._noise = np.random.default_rng([self.seed, self._restarts])
        self._restarts += 1
        self._k = 0  # samples since the restart

    def _next_readings(self) -> NDArray[np.float64]:
        """Ψ [rad] of the next sample: the simulated glove's sensor model (eq. (1) with the
        person's parameters and noise) on the operator's pose at the sample's time.

        One pose per cycle (~20 us, the sensor model's single-pose path): in-process the
        emulator shares the GIL with the host loop under test, and a batch of samples
        evaluated at once would hold it for one long burst every few tens of cycles (the
        real glove computes its readings on its own processor).
        """
        theta = self._operator(self._k / self.rate_hz)
        self._k += 1
        return sensor_readings(theta, self.person, self._noise)

    # ------------------------------------------------------------------ state
    @property
    def torque_enabled(self) -> bool:
        """Whether the actuators are on."""
        with self._lock:
            return self._enabled

    @property
    def torque(self) -> NDArray[np.float64]:
        """Torques [N m] the actuators apply now (zero while disabled)."""
        with self._lock:
            return self._torque.copy()

    @property
    def fault_watchdog(self) -> bool:
        """The device-side watchdog tripped (latched until Enable with ClearFaults)."""
        with self._lock:
            return self._fault_watchdog

    def pause(self, seconds: float) -> None:
        """Send no frames at all for ``seconds`` [s] (a silent glove); commands still count."""
        with self._lock:
            self._pause_until = time.perf_counter() + float(seconds)

    # ------------------------------------------------------------------ lifetime
    def start(self) -> GloveEmulator:
        """Open the bus and start sending (idempotent).

        Raises:
            InputError: the bus cannot be opened (:func:`~ias_gym.hardware.can_glove.open_bus`).
        """
        if self._thread is not None:
            return self
        self._bus = open_bus(self.interface, self.channel, **self._bus_kwargs)
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="GloveEmulator", daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop sending and shut the bus down (idempotent)."""
        if self._thread is None:
            return
        self._stop.set()
        self._thread.join()
        self._thread = None
        self._bus.shutdown()
        self._bus = None

    def __enter__(self) -> GloveEmulator:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # ------------------------------------------------------------------ the device loop
    def _run(self) -> None:
        period = 1.0 / self.rate_hz
        deadline = time.perf_counter()
        next_status = deadline
        while not self._stop.is_set():
            now = time.perf_counter()
            if now - deadline >= period:
                self.stats.late_cycles += 1
                deadline = now  # a late cycle is not made up for by a burst
            if now >= self._pause_until:
                self._send_sample()
            if now >= next_status:
                self._send_status()
                next_status += STATUS_PERIOD
            # Like a device's main loop, commands are polled once a cycle: one wake-up per
            # sample, not one per frame (in-process, every wake-up competes for the GIL
            # with the host loop under test).
            while (msg := self._bus.recv(timeout=0.0)) is not None:
                self._on_command(msg)
            self._check_watchdog(time.perf_counter())
            deadline += period
            left = deadline - time.perf_counter()
            if left > 0:
                time.sleep(left)

    def _send(self, frame: Frame | can.Message) -> None:
        """Send a protocol frame (or a ready python-can message, e.g. an error frame)."""
        try:
            msg = to_message(frame) if isinstance(frame, Frame) else frame
            self._bus.send(msg, timeout=SEND_TIMEOUT)
            self.stats.frames_sent += 1
        except Exception:  # a full queue on the far side: the frame is lost, as on a bus
            self.stats.tx_errors += 1

    def _send_sample(self) -> None:
        psi = self._next_readings()
        if not in_sensor_range(psi, fd=self.fd):
            with self._lock:
                self._fault_sensor = True  # the converters saturate (encode_sensors clips)
        self.stats.samples += 1
        frames = encode_sensors(psi, self._counter, fd=self.fd)
        self._counter = (self._counter + 1) % 256
        if not self._faulty:  # a good glove: no draws (this runs on the host loop's GIL)
            for frame in frames:
                self._send(frame)
            return
        f, rng = self.faults, self._rng
        for frame in frames:
            if rng.random() < f.drop:
                self.stats.injected["drop"] += 1
                continue
            data = bytearray(frame.data)
            if rng.random() < f.corrupt:
                for bit in rng.choice(8 * len(data), size=rng.integers(1, 4), replace=False):
                    data[bit // 8] ^= 1 << (bit % 8)
                self.stats.injected["corrupt"] += 1
            if rng.random() < f.wrong_length:
                data = data[:-1] if rng.random() < 0.5 else data + b"\x00"
                self.stats.injected["wrong_length"] += 1
            self._send(Frame(frame.arbitration_id, bytes(data), frame.is_fd))
        if rng.random() < f.garbage:
            ident, n = self._protocol_frames[int(rng.integers(len(self._protocol_frames)))]
            self._send(Frame(ident, rng.bytes(n), n > 8))
            self.stats.injected["garbage"] += 1
        if rng.random() < f.error_frame:
            self._send(require_can().Message(is_error_frame=True, data=b""))
            self.stats.injected["error_frame"] += 1

    def _send_status(self) -> None:
        with self._lock:
            self._status_counter = (self._status_counter + 1) % 16
            frame = encode_status(
                self._enabled,
                self._fault_watchdog,
                self._fault_command,
                self._fault_sensor,
                self._status_counter,
            )
        self._send(frame)

    def _on_command(self, msg: Any) -> None:
        if msg.is_error_frame:
            return
        try:
            decoded = decode_frame(msg.arbitration_id, msg.data)
        except UnknownIdError:
            return  # another node's traffic
        except ProtocolError:
            with self._lock:
                self._fault_command = True
            self.stats.commands_rejected += 1
            return
        now = time.perf_counter()
        with self._lock:
            if decoded.name == HOST_COMMAND:
                if decoded.values["ClearFaults"]:
                    self._fault_watchdog = self._fault_command = self._fault_sensor = False
                if decoded.values["Enable"]:  # (re)start: the person begins the task afresh
                    self._enabled = True
                    self._last_command_time = now
                    self._restart_person()
                elif not decoded.values["Enable"]:
                    self._enabled = False
                    self._torque = np.zeros(len(ACTUATED_JOINTS))
            elif decoded.name == TORQUE_COMMAND:
                self._on_torque(decoded, now)

    def _on_torque(self, decoded: Any, now: float) -> None:
        counter = int(decoded.values["Counter"])
        torques = torques_of(decoded)
        if counter == self._last_cmd_counter:
            # A repeat is a safety command: only zero torque is taken from it.
            self.stats.safety_commands += 1
            if not torques.any():
                self._torque = torques
            return
        if self._last_cmd_counter is not None:
            self.stats.commands_lost += (counter - self._last_cmd_counter) % 16 - 1
        self._last_cmd_counter = counter
        self._last_command_time = now
        self.stats.commands += 1
        self.command_age.append((self._counter - 1 - int(decoded.values["SampleCounter"])) % 256)
        self._torque = torques if self._enabled else np.zeros(len(ACTUATED_JOINTS))
        self.applied.append((now, self._torque.copy()))

    def _check_watchdog(self, now: float) -> None:
        with self._lock:
            if self._enabled and now - self._last_command_time > self.watchdog_timeout:
                self._enabled = False
                self._torque = np.zeros(len(ACTUATED_JOINTS))
                self._fault_watchdog = True
                self.stats.watchdog_trips += 1


_FAULT_KINDS = ("drop", "corrupt", "wrong_length", "garbage", "error_frame")


def _protocol_frames() -> list[tuple[int, int]]:
    """(id, DBC length) of every protocol message."""
    from ias_gym.hardware.protocol import database

    return [(int(m.frame_id), int(m.length)) for m in database().messages]

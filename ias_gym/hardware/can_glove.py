"""The real glove on a CAN bus: a :class:`~ias_gym.glove.device.GloveDevice` over python-can.

:class:`CanGlove` opens ``can.Bus(interface=..., channel=..., **bus_kwargs)``, so every
python-can backend works (socketcan, pcan, kvaser, virtual, ...). A background thread
receives frames, checks them (:class:`~ias_gym.hardware.samples.FrameReceiver`: lengths,
ranges, counters) and keeps the newest complete sample; :meth:`CanGlove.read` returns it
without waiting on the bus. The same thread is the host-side watchdog, armed while the glove
is enabled: when no valid sample has arrived for ``watchdog_timeout`` [s] it sends a
zero-torque command and disables the glove's actuators, sets :attr:`CanGlove.fault`, and
every later command carries zero torque until :meth:`CanGlove.enable`.

Safety commands (watchdog, close) repeat the last command counter: host cycles always count
up by one, so a log of the session tells them apart (the replay needs this). A session log is
written beside its destination and moved there when the glove closes (a crashed session
leaves ``.NAME.partial-PID.SUFFIX``, never half a file under the name asked for); an existing
file is only replaced with ``overwrite=True``.
"""

from __future__ import annotations

import dataclasses
import os
import threading
import time
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from ias_gym.errors import (
    GloveTimeoutError,
    InputError,
)
from ias_gym.glove.device import ACTUATED_JOINTS, GloveDevice, GloveReading
from ias_gym.glove.ids import check_id
from ias_gym.glove.profile import DEFAULT_GLOVE_ID
from ias_gym.hardware.bus import (
    RECORD_SUFFIXES,
    SEND_TIMEOUT,
    check_interface,
    check_record_path,
    open_bus,
    require_can,
    to_message,
)
from ias_gym.hardware.protocol import (
    BITRATE,
    Frame,
    encode_host_command,
    encode_torque,
)
from ias_gym.hardware.samples import FrameReceiver, LinkStats, Sample

if TYPE_CHECKING:
    import can

# The names other modules import from here (the bus helpers live in ias_gym.hardware.bus).
__all__ = [
    "RECORD_SUFFIXES",
    "SEND_TIMEOUT",
    "CanGlove",
    "GloveTimeoutError",
    "check_interface",
    "check_record_path",
    "open_bus",
    "require_can",
    "to_message",
]


class CanGlove(GloveDevice):
    """The sensor glove on a CAN bus (protocol: ``ias_gym.hardware.DBC_PATH``).

    Args:
        interface: python-can interface name (``"socketcan"``, ``"pcan"``, ``"virtual"``, ...).
        channel: the interface's channel (``"can0"``, ``"PCAN_USBBUS1"``, any name for virtual).
        fd: CAN FD (one 24-byte sensor frame per sample, bit-rate switch); default classic.
        watchdog_timeout: no valid sample for this long [s] trips the watchdog.
        startup_timeout: how long :meth:`read` waits for the first sample [s].
        glove_id: the glove's id (profiles are checked against it).
        log_path: record every frame received and sent to this python-can log file
            (:data:`RECORD_SUFFIXES`: the suffix picks the format); a session replays from
            it (:class:`~ias_gym.hardware.replay.ReplayGlove`). Written beside it and moved
            there by :meth:`close`.
        overwrite: replace an existing ``log_path`` (otherwise refused before the bus opens).
        **bus_kwargs: passed to ``can.Bus`` (``bitrate``: default 1 Mbit/s as the DBC;
            CAN FD timing such as ``data_bitrate`` as the backend wants it).

    Raises:
        InputError: a non-positive timeout, a ``log_path`` refused by
            :func:`check_record_path`, or a bus that cannot be opened (:func:`open_bus`).
    """

    def __init__(
        self,
        interface: str = "virtual",
        channel: str | int = "ias-glove",
        *,
        fd: bool = False,
        watchdog_timeout: float = 0.02,
        startup_timeout: float = 1.0,
        glove_id: str = DEFAULT_GLOVE_ID,
        log_path: str | Path | None = None,
        overwrite: bool = False,
        **bus_kwargs: Any,
    ) -> None:
        for name, value in (
            ("watchdog_timeout", watchdog_timeout),
            ("startup_timeout", startup_timeout),
        ):
            if not value > 0:
                raise InputError(f"{name} must be positive [s], got {value}")
        can = require_can()
        self.log_path = (
            None if log_path is None else check_record_path(log_path, overwrite=overwrite)
        )
        self.overwrite = bool(overwrite)
        self.interface, self.channel, self.fd = interface, channel, bool(fd)
        self.glove_id = check_id(glove_id, "glove_id")
        self.watchdog_timeout = float(watchdog_timeout)
        self.startup_timeout = float(startup_timeout)
        bus_kwargs.setdefault("bitrate", BITRATE)  # the protocol's 1 Mbit/s (backends differ)
        if fd:
            bus_kwargs.setdefault("fd", True)
        self._bus = open_bus(interface, channel, **bus_kwargs)
        self._partial: Path | None = None
        self._logger: Any = None
        if self.log_path is not None:
            self._partial = self.log_path.with_name(
                f".{self.log_path.stem}.partial-{os.getpid()}{self.log_path.suffix}"
            )
            try:
                self._logger = can.Logger(str(self._partial))
            except BaseException:
                self._bus.shutdown()
                raise
        self._log_lock = threading.Lock()
        self._send_lock = threading.Lock()
        self._state = threading.Condition()
        self._receiver = FrameReceiver(fd=self.fd)
        self._latest: tuple[Sample, float] | None = None
        self._seq = 0  # samples received
        self._read_seq = 0  # sample sequence number of the last read
        self._read_counter = 0  # counter of the last sample read (echoed in commands)
        self._last_valid: float | None = None  # time.perf_counter() of the last sample
        self._fault: str | None = None
        self._enabled = False
        self._cmd_counter = 0  # host cycles count 1, 2, ...; safety commands repeat it
        self._host_counter = 0
        self._closed = False
        #: Host-side watchdog trips, and for each the time from the last valid sample [s].
        self.watchdog_trips = 0
        self.trip_delays: list[float] = []
        #: Torques [N m] of the last command sent (after clamping; zero while off).
        self.last_command = np.zeros(len(ACTUATED_JOINTS))
        #: Commands whose torques had NaN or inf entries (sent as 0).
        self.nonfinite_commands = 0
        #: Errors of the bus (recv/send) and of frame handling, counted, never raised.
        self.bus_errors = 0
        self.last_error: str | None = None
        self._poll = min(0.0002, self.watchdog_timeout / 40.0)  # watchdog resolution [s]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._receive_loop, name="CanGlove-rx", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ GloveDevice
    @property
    def n_actuators(self) -> int:
        return len(ACTUATED_JOINTS)

    @property
    def fault(self) -> str | None:
        with self._state:
            return self._fault

    @property
    def stats(self) -> LinkStats:
        """Link statistics (a copy): frames received, invalid, dropped, duplicated, ..."""
        with self._state:
            return dataclasses.replace(self._receiver.stats)

    @property
    def device_status(self) -> dict[str, float] | None:
        """The glove's last ``GloveStatus`` (TorqueEnabled, Fault* bits), None before one."""
        with self._state:
            return None if self._receiver.status is None else dict(self._receiver.status)

    def read(self) -> GloveReading:
        """The newest complete sample (the same one again if none came since the last read).

        Waits for the first sample up to ``startup_timeout``; after a watchdog trip it returns
        the last sample and :attr:`fault` says why it is stale.

        Raises:
            GloveTimeoutError: no sample has ever arrived within ``startup_timeout``.
        """
        self._check_open()
        with self._state:
            if self._latest is None and not self._state.wait_for(
                lambda: self._latest is not None, self.startup_timeout
            ):
                raise GloveTimeoutError(self._silence_message(self.startup_timeout))
            assert self._latest is not None
            sample, stamp = self._latest
            self._read_seq, self._read_counter = self._seq, sample.counter
        return GloveReading(psi=sample.psi.copy(), timestamp=stamp)

    def wait_for_sample(self, timeout: float | None = None) -> GloveReading:
        """Block until a sample newer than the last read arrives, and read it.

        Raises:
            GloveTimeoutError: none within ``timeout`` [s] (default ``startup_timeout``).
        """
        self._check_open()
        timeout = self.startup_timeout if timeout is None else timeout
        with self._state:
            seq = self._read_seq
            if not self._state.wait_for(lambda: self._seq > seq, timeout):
                raise GloveTimeoutError(self._silence_message(timeout))
        return self.read()

    def write_feedback(self, torques: ArrayLike) -> None:
        """Send one host cycle's torques [N m] for :data:`ACTUATED_JOINTS`.

        NaN or inf entries are sent as 0 (counted in :attr:`nonfinite_commands`), the rest
        clamped to the actuators' limits; while the glove is disabled or has a fault the
        command carries zero torque. The command echoes the counter of the last sample read.

        Raises:
            ValueError: wrong shape (nothing is sent).
        """
        self._check_open()
        t = np.array(torques, dtype=np.float64)
        if t.shape != (self.n_actuators,):
            raise ValueError(f"torques must have shape ({self.n_actuators},), got {t.shape}")
        if not np.isfinite(t).all():
            self.nonfinite_commands += 1
        with self._state:
            if self._fault is not None or not self._enabled:
                t = np.zeros(self.n_actuators)
            self._cmd_counter = (self._cmd_counter + 1) % 16
            frame, applied = encode_torque(t, self._cmd_counter, self._read_counter, fd=self.fd)
        self.last_command = applied
        self._send(frame)

    def enable(self) -> None:
        """Clear the fault, enable the glove's actuators; the watchdog re-arms with the next
        valid sample."""
        self._check_open()
        with self._state:
            self._fault = None
            self._enabled = True
            # Re-armed by the next valid sample: a glove that stays silent after the enable
            # is reported by wait_for_sample / read, not by an instant trip.
            self._last_valid = None
        self._send_host_command(enable=True)

    def disable(self) -> None:
        """Zero torque and disable the glove's actuators (until :meth:`enable`)."""
        self._check_open()
        with self._state:
            self._enabled = False
        self._send_safety_zero()
        self._send_host_command(enable=False)

    def close(self) -> None:
        """Zero torque, disable the actuators, stop the receiver, shut the bus down (idempotent)."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        self._thread.join()
        self._send_safety_zero()
        self._send_host_command(enable=False)
        if self._logger is not None:
            with self._log_lock:
                self._logger.stop()
            self._finish_log()
        self._bus.shutdown()

    def __enter__(self) -> CanGlove:
        return self

    # ------------------------------------------------------------------ internals
    def _finish_log(self) -> None:
        """Move the finished log to ``log_path``; one that appeared there meanwhile is kept
        (without ``overwrite``) and the session stays at the partial name, with a warning."""
        assert self._partial is not None and self.log_path is not None
        if self.overwrite:
            os.replace(self._partial, self.log_path)
            return
        try:
            os.link(self._partial, self.log_path)  # fails if the name was taken meanwhile
        except FileExistsError:
            warnings.warn(
                f"{self.log_path} appeared while the session was recorded; the session is "
                f"kept as {self._partial}",
                RuntimeWarning,
                stacklevel=3,
            )
            return
        except OSError:  # a file system without hard links: the check was made at the start
            os.replace(self._partial, self.log_path)
            return
        os.unlink(self._partial)

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError(f"CAN glove on {self.interface}:{self.channel} is closed")

    def _silence_message(self, timeout: float) -> str:
        return (
            f"no sensor sample from the glove on {self.interface}:{self.channel} within "
            f"{timeout} s ({self.stats.frames_received} frames received): is the glove (or "
            f"`ias-gym glove-emulator`) running on this channel, with fd={self.fd}?"
        )

    def _send(self, frame: Frame) -> None:
        msg = to_message(frame)
        with self._send_lock:
            try:
                self._bus.send(msg, timeout=SEND_TIMEOUT)
            except Exception as e:  # a full tx queue or bus-off must not kill the host loop
                self.bus_errors += 1
                self.last_error = f"send: {e!r}"
                return
            if self._logger is not None:
                with self._log_lock:
                    self._logger(msg)

    def _send_safety_zero(self) -> None:
        with self._state:
            frame, applied = encode_torque(
                np.zeros(self.n_actuators), self._cmd_counter, self._read_counter, fd=self.fd
            )
        self.last_command = applied
        self._send(frame)

    def _send_host_command(self, enable: bool) -> None:
        with self._state:
            self._host_counter = (self._host_counter + 1) % 16
            frame = encode_host_command(enable, enable, self._host_counter)
        self._send(frame)

    def _receive_loop(self) -> None:
        while not self._stop.is_set():
            # Wake for frames, and for the watchdog's deadline (not more often: every
            # wake-up takes the GIL from the host loop).
            with self._state:
                last = self._last_valid
            timeout = (
                self._poll
                if last is None
                else min(max(last + self.watchdog_timeout - time.perf_counter(), 0.0), 0.05)
                + self._poll
            )
            try:
                msg = self._bus.recv(timeout=timeout)
            except Exception as e:  # the backend's errors are counted, never raised here
                self.bus_errors += 1
                self.last_error = f"recv: {e!r}"
                self._stop.wait(self._poll)
                msg = None
            now = time.perf_counter()
            if msg is not None:
                try:
                    self._handle(msg, now)
                except Exception as e:  # a frame we cannot handle is counted, not fatal
                    self.bus_errors += 1
                    self.last_error = f"frame {msg}: {e!r}"
            self._check_watchdog(now)

    def _handle(self, msg: can.Message, now: float) -> None:
        if self._logger is not None:
            with self._log_lock:
                self._logger(msg)
        with self._state:
            out = self._receiver.feed(msg.arbitration_id, msg.data, msg.is_error_frame)
            if isinstance(out, Sample):
                self._latest = (out, float(msg.timestamp))
                self._seq += 1
                self._last_valid = now
                self._state.notify_all()

    def _check_watchdog(self, now: float) -> None:
        with self._state:
            if (
                not self._enabled  # nothing to make safe: no torque is commanded
                or self._last_valid is None
                or self._fault is not None
                or now - self._last_valid <= self.watchdog_timeout
            ):
                return
            delay = now - self._last_valid
            self._fault = (
                f"watchdog: no valid sensor sample for {delay * 1e3:.1f} ms "
                f"(limit {self.watchdog_timeout * 1e3:.0f} ms); torque off until enable()"
            )
            self.watchdog_trips += 1
            self.trip_delays.append(delay)
        self._send_safety_zero()
        self._send_host_command(enable=False)

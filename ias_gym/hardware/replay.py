"""Replaying a recorded glove session from its python-can log, deterministically.

A :class:`~ias_gym.hardware.can_glove.CanGlove` with ``log_path`` records every frame it
received and sent. Each host cycle reads one sample and sends one ``TorqueCommand`` that
echoes the sample's counter (``SampleCounter``); safety commands (watchdog, close) repeat the
last command counter. :class:`ReplayGlove` rebuilds from the log, through the same
:class:`~ias_gym.hardware.samples.FrameReceiver` as the live host, the sample every host
cycle used, in order: the env stepped on it sees the recorded session's readings exactly,
so with the same actions it reproduces the observations bit for bit.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ias_gym.errors import (
    ReplayError,
)
from ias_gym.glove.device import ACTUATED_JOINTS, GloveDevice, GloveReading
from ias_gym.glove.profile import DEFAULT_GLOVE_ID
from ias_gym.hardware.can_glove import RECORD_SUFFIXES, require_can
from ias_gym.hardware.protocol import (
    HOST_COMMAND,
    TORQUE_COMMAND,
    ProtocolError,
    decode_frame,
    frame_id,
    torques_of,
)
from ias_gym.hardware.samples import FrameReceiver, Sample

if TYPE_CHECKING:
    import can


class ReplayGlove(GloveDevice):
    """A :class:`~ias_gym.glove.device.GloveDevice` that plays a recorded session back.

    Args:
        path: the python-can log written by ``CanGlove(log_path=...)``.
        fd: the session used CAN FD sensor frames.
        glove_id: the glove's id.

    Attributes:
        recorded_torques: ``(n_cycles, 5)`` torques [N m] the live host sent, per cycle.
        feedback: torques [N m] written during the replay, one per :meth:`write_feedback`.

    Raises:
        ReplayError: no such file, a suffix other than ``.asc``, ``.blf``, ``.log``, a file
            python-can cannot read (not a log, empty, truncated), no host cycle in the log, or
            one whose sample is not in it.
    """

    def __init__(
        self, path: str | Path, *, fd: bool = False, glove_id: str = DEFAULT_GLOVE_ID
    ) -> None:
        self.path = Path(path)
        self.glove_id = glove_id
        receiver = FrameReceiver(fd=fd)
        by_counter: dict[int, tuple[Sample, float]] = {}
        self._cycles: list[tuple[Sample, float]] = []
        torques: list[NDArray[np.float64]] = []
        torque_id = frame_id(TORQUE_COMMAND)
        last_counter = 0
        last_sent = None  # the last frame the host sent: a complete session ends with Disable
        for msg in _read_log(self.path):
            if msg.is_rx:
                out = receiver.feed(msg.arbitration_id, msg.data, msg.is_error_frame)
                if isinstance(out, Sample):
                    by_counter[out.counter] = (out, float(msg.timestamp))
                continue
            last_sent = msg
            if msg.arbitration_id != torque_id:
                continue
            try:
                decoded = decode_frame(msg.arbitration_id, msg.data)
            except ProtocolError as e:
                raise ReplayError(
                    f"replay={str(self.path)!r}: a sent command is malformed: {e}"
                ) from None
            counter = int(decoded.values["Counter"])
            if counter == last_counter:
                continue  # a safety command, not a host cycle
            last_counter = counter
            echoed = int(decoded.values["SampleCounter"])
            if echoed not in by_counter:
                raise ReplayError(
                    f"replay={str(self.path)!r}: host cycle {len(self._cycles)} used sample "
                    f"{echoed}, which is not in the log (was it recorded with record=...?)"
                )
            self._cycles.append(by_counter[echoed])
            torques.append(torques_of(decoded))
        if not self._cycles:
            raise ReplayError(
                f"replay={str(self.path)!r}: no host cycles (TorqueCommand frames) in the log; "
                "is it a session recorded with record=... ?"
            )
        if not _is_disable(last_sent):
            raise ReplayError(
                f"replay={str(self.path)!r} is truncated: it stops after {len(self._cycles)} "
                "host cycles without the Disable command a recorded session ends with (sent "
                "when the glove closes); was the recording cut short, or copied in part?"
            )
        self.recorded_torques = np.array(torques)
        self.feedback: list[NDArray[np.float64]] = []
        self._k = 0
        self._closed = False

    def __len__(self) -> int:
        """Number of host cycles in the session."""
        return len(self._cycles)

    @property
    def n_actuators(self) -> int:
        return len(ACTUATED_JOINTS)

    @property
    def fault(self) -> str | None:
        if self._k > len(self._cycles):
            return f"replay: the recorded session ended after {len(self._cycles)} host cycles"
        return None

    def read(self) -> GloveReading:
        """The sample of the next recorded host cycle (the last again once the log ends)."""
        if self._closed:
            raise RuntimeError(f"replay of {self.path} is closed")
        sample, stamp = self._cycles[min(self._k, len(self._cycles) - 1)]
        self._k += 1
        return GloveReading(psi=sample.psi.copy(), timestamp=stamp)

    def write_feedback(self, torques: ArrayLike) -> None:
        t = np.array(torques, dtype=np.float64)
        if t.shape != (self.n_actuators,):
            raise ValueError(f"torques must have shape ({self.n_actuators},), got {t.shape}")
        self.feedback.append(t)

    def close(self) -> None:
        self._closed = True


def _is_disable(msg: can.Message | None) -> bool:
    """Whether ``msg`` is a ``HostCommand`` with Enable = 0 (the end of every session)."""
    if msg is None or msg.arbitration_id != frame_id(HOST_COMMAND):
        return False
    try:
        return decode_frame(msg.arbitration_id, msg.data).values["Enable"] == 0
    except ProtocolError:
        return False


def _read_log(path: Path) -> Iterator[can.Message]:
    """The messages of a python-can log, one by one, or a :class:`ReplayError` naming the file.

    python-can's readers fail in their own ways on a file that is not theirs (``struct.error``
    on an empty ``.blf``, ``ValueError`` on a line it cannot split, ...), or stop early on a
    truncated one; all of them become one error that says what the file should be.
    """
    can = require_can()
    what = f"replay={str(path)!r}"
    if path.suffix.lower() not in RECORD_SUFFIXES:
        raise ReplayError(
            f"{what}: a recorded session is a {', '.join(RECORD_SUFFIXES)} file "
            "(written by record=...); this suffix is none of them"
        )
    if not path.is_file():
        raise ReplayError(f"{what}: no such file")
    if path.stat().st_size == 0:
        raise ReplayError(f"{what} is empty: not a recorded session")
    # The reader gets a file opened here, closed here: python-can's LogReader opens its own
    # and leaks it when the reader's constructor fails on a foreign file (ResourceWarning).
    reader_class, mode = {
        ".asc": (can.ASCReader, "r"),
        ".blf": (can.BLFReader, "rb"),
        ".log": (can.CanutilsLogReader, "r"),
    }[path.suffix.lower()]
    try:
        with open(path, mode) as file, reader_class(file) as reader:
            yield from reader
    except Exception as e:  # the readers' many ways of saying "not my format"
        raise ReplayError(
            f"{what} is not a readable python-can {path.suffix} log ({type(e).__name__}: {e}); "
            "give a session recorded with record=..."
        ) from e

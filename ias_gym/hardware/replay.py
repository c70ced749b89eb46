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

from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ias_gym.errors import IasGymError
from ias_gym.glove.device import ACTUATED_JOINTS, GloveDevice, GloveReading
from ias_gym.glove.profile import DEFAULT_GLOVE_ID
from ias_gym.hardware.can_glove import require_can
from ias_gym.hardware.protocol import (
    TORQUE_COMMAND,
    ProtocolError,
    decode_frame,
    frame_id,
    torques_of,
)
from ias_gym.hardware.samples import FrameReceiver, Sample


class ReplayError(IasGymError, ValueError):
    """The log is not a recorded glove session (no host cycles, or a cycle without its sample)."""


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
        ReplayError: no host cycle in the log, or one whose sample is not in it.
    """

    def __init__(
        self, path: str | Path, *, fd: bool = False, glove_id: str = DEFAULT_GLOVE_ID
    ) -> None:
        can = require_can()
        self.path = Path(path)
        self.glove_id = glove_id
        receiver = FrameReceiver(fd=fd)
        by_counter: dict[int, tuple[Sample, float]] = {}
        self._cycles: list[tuple[Sample, float]] = []
        torques: list[NDArray[np.float64]] = []
        torque_id = frame_id(TORQUE_COMMAND)
        last_counter = 0
        with can.LogReader(str(self.path)) as reader:
            for msg in reader:
                if msg.is_rx:
                    out = receiver.feed(msg.arbitration_id, msg.data, msg.is_error_frame)
                    if isinstance(out, Sample):
                        by_counter[out.counter] = (out, float(msg.timestamp))
                    continue
                if msg.arbitration_id != torque_id:
                    continue
                try:
                    decoded = decode_frame(msg.arbitration_id, msg.data)
                except ProtocolError as e:
                    raise ReplayError(f"{self.path}: a sent command is malformed: {e}") from None
                counter = int(decoded.values["Counter"])
                if counter == last_counter:
                    continue  # a safety command, not a host cycle
                last_counter = counter
                echoed = int(decoded.values["SampleCounter"])
                if echoed not in by_counter:
                    raise ReplayError(
                        f"{self.path}: host cycle {len(self._cycles)} used sample {echoed}, "
                        "which is not in the log (was it recorded with CanGlove(log_path=...)?)"
                    )
                self._cycles.append(by_counter[echoed])
                torques.append(torques_of(decoded))
        if not self._cycles:
            raise ReplayError(f"{self.path}: no host cycles (TorqueCommand frames) in the log")
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

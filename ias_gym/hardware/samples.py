"""From received frames to glove samples: pairing, counters, link statistics (pure, no bus).

Both the live :class:`~ias_gym.hardware.can_glove.CanGlove` and the log replay
(:mod:`ias_gym.hardware.replay`) feed frames through :class:`FrameReceiver`, so a replayed
session assembles exactly the samples the live host did.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ias_gym.glove.hand import N_SENSORS
from ias_gym.hardware.protocol import (
    GLOVE_STATUS,
    Decoded,
    ProtocolError,
    UnknownIdError,
    decode_frame,
    readings_of,
    sensor_messages,
)


@dataclass
class LinkStats:
    """Counts of what arrived on the link (host side).

    Attributes:
        frames_received: data frames received (any id).
        frames_invalid: protocol ids with a wrong length or a value out of range (dropped).
        frames_unknown: ids not in the protocol (other nodes on the bus; ignored).
        frames_dropped: sensor frames missing, from gaps in their 8-bit counters.
        frames_duplicated: sensor frames repeating the last counter (ignored).
        error_frames: CAN error frames.
        samples: complete samples (all sensor frames of one counter value).
    """

    frames_received: int = 0
    frames_invalid: int = 0
    frames_unknown: int = 0
    frames_dropped: int = 0
    frames_duplicated: int = 0
    error_frames: int = 0
    samples: int = 0

    def as_dict(self) -> dict[str, int]:
        """The counts as a plain dict."""
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class Sample:
    """A complete sensor sample: its 8-bit counter and the 10 readings Ψ [rad]."""

    counter: int
    psi: NDArray[np.float64]


class FrameReceiver:
    """Checks and assembles received frames (not thread-safe: one receiver feeds it).

    Args:
        fd: the glove sends CAN FD sensor frames (one per sample) instead of two classic ones.
    """

    def __init__(self, fd: bool = False) -> None:
        self.messages = sensor_messages(fd)
        self.stats = LinkStats()
        self._last_counter: dict[str, int] = {}
        self._parts: dict[str, tuple[int, dict[int, float]]] = {}
        #: The last decoded ``GloveStatus`` values, or None before the first.
        self.status: dict[str, float] | None = None

    def feed(
        self, arbitration_id: int, data: bytes | bytearray, is_error_frame: bool = False
    ) -> Sample | Decoded | None:
        """Take one received frame.

        Returns:
            the :class:`Sample` this frame completes; the :class:`Decoded` frame when it is a
            valid protocol frame that is not a sensor frame (status, another host's commands);
            None when it was counted and dropped, or is a part of a sample still incomplete.
        """
        if is_error_frame:
            self.stats.error_frames += 1
            return None
        self.stats.frames_received += 1
        try:
            decoded = decode_frame(arbitration_id, data)
        except UnknownIdError:
            self.stats.frames_unknown += 1
            return None
        except ProtocolError:
            self.stats.frames_invalid += 1
            return None
        if decoded.name == GLOVE_STATUS:
            self.status = decoded.values
            return decoded
        if decoded.name not in self.messages:
            return decoded
        return self._add_sensor_frame(decoded)

    def _add_sensor_frame(self, decoded: Decoded) -> Sample | None:
        counter = int(decoded.values["Counter"])
        last = self._last_counter.get(decoded.name)
        if last is not None:
            gap = (counter - last) % 256
            if gap == 0:
                self.stats.frames_duplicated += 1
                return None
            self.stats.frames_dropped += gap - 1
        self._last_counter[decoded.name] = counter
        self._parts[decoded.name] = (counter, readings_of(decoded))
        if any(self._parts.get(m, (-1,))[0] != counter for m in self.messages):
            return None  # the other part of this sample has not come (or was lost)
        psi = np.full(N_SENSORS, np.nan)
        for m in self.messages:
            for i, v in self._parts.pop(m)[1].items():
                psi[i] = v
        self.stats.samples += 1
        return Sample(counter, psi)

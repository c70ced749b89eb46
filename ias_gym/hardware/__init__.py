"""The real glove on a CAN bus (paper 2.1-2.3): protocol, device, emulator, hardware env.

- :data:`DBC_PATH`: the glove's CAN protocol as a DBC file (read and written with cantools);
  :mod:`~ias_gym.hardware.protocol` encodes and decodes it (pure, range-checked) and
  computes its bus load.
- :class:`CanGlove`: the glove as a :class:`~ias_gym.glove.device.GloveDevice` over any
  python-can backend, with a background receiver and the host-side watchdog.
- :class:`GloveEmulator`: the glove's side of the protocol with a simulated person behind it
  (``ias-gym glove-emulator``), with fault injection (:class:`FaultInjection`).
- :class:`GloveHardwareEnv`: ``IAS-GloveHardware-v0``; sessions are recorded to python-can
  logs and replayed (:class:`ReplayGlove`).
- :mod:`~ias_gym.hardware.bench`: ``ias-gym glove-bench``, the host loop against the
  emulator, and its statistics (:class:`LoopStats`).

python-can and cantools are the ``[hardware]`` extra; importing this package does not need
them, opening a bus or reading the DBC does (the error says which extra to install).
"""

from __future__ import annotations

from ias_gym.hardware.can_glove import CanGlove, GloveTimeoutError
from ias_gym.hardware.emulator import EmulatorStats, FaultInjection, GloveEmulator
from ias_gym.hardware.env import GloveHardwareEnv
from ias_gym.hardware.loop import LoopClock, LoopStats, loop_stats
from ias_gym.hardware.protocol import DBC_PATH, ProtocolError, bus_load, database
from ias_gym.hardware.replay import ReplayError, ReplayGlove
from ias_gym.hardware.samples import FrameReceiver, LinkStats, Sample

__all__ = [
    "DBC_PATH",
    "CanGlove",
    "EmulatorStats",
    "FaultInjection",
    "FrameReceiver",
    "GloveEmulator",
    "GloveHardwareEnv",
    "GloveTimeoutError",
    "LinkStats",
    "LoopClock",
    "LoopStats",
    "ProtocolError",
    "ReplayError",
    "ReplayGlove",
    "Sample",
    "bus_load",
    "database",
    "loop_stats",
]

"""Opening the CAN bus and recording it: python-can on demand, the checked interface name and
session-log path, the bus itself, and :class:`~ias_gym.hardware.protocol.Frame` ->
``can.Message``. Split out of :mod:`ias_gym.hardware.can_glove`, which re-exports these names
(the emulator, the replay and the bench use them too).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ias_gym.errors import InputError
from ias_gym.hardware.protocol import (
    Frame,
)

if TYPE_CHECKING:
    import can


def require_can() -> Any:
    """Import python-can, or say which extra to install."""
    try:
        import can
    except ImportError as e:  # pragma: no cover - exercised without the extra
        raise ImportError(
            "the CAN glove needs python-can and cantools: pip install 'ias-gym[hardware]'"
        ) from e
    return can


#: Log formats a session is recorded in: python-can writes and reads them back with the
#: direction of every frame and CAN FD (``.csv``, ``.db`` lose the direction, ``.trc`` FD).
RECORD_SUFFIXES = (".asc", ".blf", ".log")


def check_record_path(path: str | Path, *, overwrite: bool = False) -> Path:
    """Check where a session is to be recorded, before anything is opened.

    Args:
        path: the log file; its suffix picks the format (:data:`RECORD_SUFFIXES`).
        overwrite: replace an existing file (when the session ends).

    Raises:
        InputError: an unsupported suffix, a missing directory, a directory at ``path``, or an
            existing file without ``overwrite=True``.
    """
    p = Path(path)
    if p.suffix.lower() not in RECORD_SUFFIXES:
        raise InputError(
            f"record={str(p)!r}: a session is recorded as {', '.join(RECORD_SUFFIXES)} "
            "(python-can keeps each frame's direction in those); choose one of these suffixes"
        )
    if not p.parent.is_dir():
        raise InputError(f"record={str(p)!r}: the directory {str(p.parent)!r} does not exist")
    if p.is_dir():
        raise InputError(f"record={str(p)!r} is a directory; give a file name")
    if p.exists() and not overwrite:
        raise InputError(
            f"record={str(p)!r} exists (a recorded session is never overwritten silently); "
            "choose another file, or pass overwrite=True to replace it"
        )
    return p


def check_interface(interface: str) -> str:
    """Check a python-can interface name (imports python-can).

    Raises:
        InputError: python-can has no such interface (the message lists those it has).
        ImportError: python-can is not installed (the message says which extra).
    """
    can = require_can()
    if interface not in can.VALID_INTERFACES:
        raise InputError(
            f"unknown CAN interface {interface!r}; python-can has: "
            f"{', '.join(sorted(can.VALID_INTERFACES))}"
        )
    return interface


def open_bus(interface: str, channel: str | int, **bus_kwargs: Any) -> can.BusABC:
    """``can.Bus(interface=..., channel=..., **bus_kwargs)``, with an error that says what to fix.

    Raises:
        InputError: an unknown interface, or one this machine cannot open (no driver, no
            SocketCAN in the kernel, no such channel, bad settings): the message names the
            interface, the channel and python-can's reason.
    """
    can = require_can()
    check_interface(interface)
    try:
        return can.Bus(interface=interface, channel=channel, **bus_kwargs)
    except (can.CanError, OSError, ImportError, ValueError, TypeError) as e:
        hint = (
            " (is SocketCAN in this machine's kernel, and the interface up? "
            "`ip link show`; without CAN hardware use --interface virtual)"
            if interface == "socketcan"
            else ""
        )
        raise InputError(
            f"cannot open CAN interface {interface!r} channel {channel!r}: {e}{hint}"
        ) from e


def to_message(frame: Frame) -> can.Message:
    """A python-can message (11-bit id; bit-rate switch for CAN FD) for a protocol frame."""
    can = require_can()
    return can.Message(
        timestamp=time.time(),
        arbitration_id=frame.arbitration_id,
        data=frame.data,
        is_extended_id=False,
        is_fd=frame.is_fd,
        bitrate_switch=frame.is_fd,
        is_rx=False,
    )


#: How long a send may wait for room in the transmit queue [s]; a frame that finds none is
#: counted as lost (python-can's virtual bus would otherwise block for ever on a full
#: receiver queue).
SEND_TIMEOUT = 0.001

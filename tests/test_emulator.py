"""The glove emulator (ias_gym.hardware.emulator): its device-side watchdog turns torque
off when the host goes quiet (python-can's virtual bus, no hardware). Every warning is an
error here, and so is any python-can log record at WARNING or above."""

from __future__ import annotations

import time

import numpy as np
import pytest

from ias_gym.hardware import (
    CanGlove,
    GloveEmulator,
)

pytestmark = [
    pytest.mark.realtime,
    pytest.mark.filterwarnings("error"),
    pytest.mark.usefixtures("no_python_can_warnings", "no_gc_pauses"),
]


def test_device_watchdog_turns_torque_off_without_commands(channel: str) -> None:
    with GloveEmulator(channel=channel, rate_hz=500) as emu, CanGlove(channel=channel) as glove:
        glove.read()
        glove.enable()
        glove.write_feedback(np.full(5, 0.2))
        time.sleep(0.01)
        assert emu.torque_enabled and emu.torque.max() == pytest.approx(0.2)
        time.sleep(0.08)  # the host goes quiet: no command for 80 ms
        assert not emu.torque_enabled and not emu.torque.any() and emu.fault_watchdog
        time.sleep(0.05)
        status = glove.device_status
        assert status is not None and status["FaultWatchdog"] == 1
        assert emu.stats.watchdog_trips == 1
        glove.enable()  # the explicit re-enable clears it
        glove.write_feedback(np.full(5, 0.1))
        time.sleep(0.01)
        assert emu.torque_enabled and not emu.fault_watchdog

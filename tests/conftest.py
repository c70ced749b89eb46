"""Fixtures shared by the CAN tests (python-can's virtual bus); headless rendering."""

from __future__ import annotations

import gc
import itertools
import logging
import os
from collections.abc import Iterator

import pytest

# Offscreen rendering without a display, for a bare `pytest` as for `make test`: MuJoCo reads
# MUJOCO_GL when it is first imported, which may be any test module's collection.
os.environ.setdefault("MUJOCO_GL", "egl")

_channels = itertools.count()


@pytest.fixture
def channel() -> str:
    """A virtual-bus channel of this test alone (virtual buses of one name share frames)."""
    return f"ias-test-{next(_channels)}"


@pytest.fixture
def no_python_can_warnings(caplog: pytest.LogCaptureFixture) -> Iterator[None]:
    """Fail a test during which python-can logged a warning (e.g. a bus not shut down)."""
    caplog.set_level(logging.WARNING, logger="can")
    yield
    records = caplog.get_records("setup") + caplog.get_records("call")
    bad = [r.getMessage() for r in records if r.name.startswith("can")]
    assert not bad, bad


@pytest.fixture
def no_gc_pauses() -> Iterator[None]:
    """No full garbage collection during a live-bus test.

    Late in the suite the heap is large and a full collection stops the interpreter, emulator
    thread included, for 50-115 ms (measured with ``gc.callbacks``): longer than the glove's
    20 ms watchdog, which then trips in a test about the protocol, not about the collector. The
    hardware env freezes the heap at reset for the same reason (``GloveHardwareEnv.reset``).
    """
    gc.collect()
    gc.freeze()
    gc.disable()
    try:
        yield
    finally:
        gc.enable()
        gc.unfreeze()

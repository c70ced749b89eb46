"""Whether ``render_mode="human"`` can open a MuJoCo window here (checked before the viewer
is created, because the viewer aborts the interpreter where it cannot); split out of
:mod:`ias_gym.envs.pen_hand_env`, which re-exports :func:`check_window_possible`.
"""

from __future__ import annotations

import os
import sys

from ias_gym.errors import InputError


def check_window_possible() -> None:
    """Raise if ``render_mode="human"`` cannot open a window here.

    MuJoCo's GLFW viewer does not raise without a display: it fails an assertion and aborts
    the interpreter (SIGABRT), so the check comes before the viewer is created.

    Raises:
        InputError: ``MUJOCO_GL`` is ``egl`` or ``osmesa`` (off-screen only), or on Linux
            neither ``DISPLAY`` nor ``WAYLAND_DISPLAY`` is set.
    """
    backend = os.environ.get("MUJOCO_GL", "").strip().lower()
    if backend in ("egl", "osmesa"):
        reason = f"MUJOCO_GL={backend} renders off-screen only"
    elif sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        reason = "there is no display (neither DISPLAY nor WAYLAND_DISPLAY is set)"
    else:
        return
    raise InputError(
        f'render_mode="human" opens a window, but {reason}; use render_mode="rgb_array" '
        "(frames as arrays, e.g. for a video) or run with a display"
    )

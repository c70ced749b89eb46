"""``render_mode="human"`` where no window can open raises instead of aborting the process.

MuJoCo's GLFW viewer fails an assertion without a display and aborts the interpreter
(SIGABRT), which no ``try`` catches; so the tests run the env in a subprocess, where such a
regression shows as a signal instead of killing pytest.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from ias_gym.errors import InputError

SCRIPT = """
import gymnasium as gym
import ias_gym
from ias_gym.errors import InputError
try:
    env = gym.make("IAS-PenSlide-v0", render_mode="human")
    env.reset(seed=0)
    env.render()
except InputError as exc:
    print("InputError:", exc)
else:
    print("a window opened")
"""


def _run(**environment: str | None) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    for key, value in environment.items():
        if value is None:
            env.pop(key, None)
        else:
            env[key] = value
    return subprocess.run(
        [sys.executable, "-c", SCRIPT],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        check=False,
    )


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="DISPLAY is X11's (Linux)")
def test_human_render_without_display_raises_input_error() -> None:
    result = _run(DISPLAY=None, WAYLAND_DISPLAY=None, MUJOCO_GL=None)
    assert result.returncode == 0, f"exit {result.returncode}: {result.stderr[-500:]}"
    assert result.stdout.startswith("InputError:"), result.stdout
    assert "no display" in result.stdout and 'render_mode="rgb_array"' in result.stdout


def test_human_render_with_an_offscreen_backend_raises_input_error() -> None:
    # A DISPLAY that is set (even to a server that does not exist) does not help: EGL and
    # OSMesa render off-screen only.
    result = _run(DISPLAY=":99", MUJOCO_GL="egl")
    assert result.returncode == 0, f"exit {result.returncode}: {result.stderr[-500:]}"
    assert result.stdout.startswith("InputError:"), result.stdout
    assert "MUJOCO_GL=egl" in result.stdout and 'render_mode="rgb_array"' in result.stdout


def test_glove_env_has_no_window_viewer() -> None:
    # (gym.make wraps it in gymnasium's HumanRendering instead, which raises its own error
    # without pygame or a display.)
    from ias_gym.envs.glove_grasp import GloveGraspEnv

    with pytest.raises(InputError, match="no window viewer, use rgb_array"):
        GloveGraspEnv(render_mode="human")

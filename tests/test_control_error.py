"""Fig. 9's table (``control_error_table``) starts where its ``options`` say.

What the table shows is checked in test_controller.py; here only that ``options`` reaches
``env.reset``, which is what a check of the figure from nearby starts relies on.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.figures.control_error import control_error_table


def test_table_starts_from_the_given_state() -> None:
    """Seed 0 with seed 1's start (same initial error) is seed 1's table, bit for bit."""
    env = gym.make("IAS-PenRotate-v0", initial_error=(0.1, 0.1))  # as the table makes it
    data = env.unwrapped.data  # type: ignore[attr-defined]
    env.reset(seed=0)
    qpos_0 = data.qpos.copy()
    env.reset(seed=1)
    start_1 = {"qpos": data.qpos.copy(), "qvel": data.qvel.copy()}
    assert np.abs(start_1["qpos"] - qpos_0).max() > 1e-4  # the seeds start apart
    moved = control_error_table(initial_error=0.1, seed=0, options=start_1)
    np.testing.assert_array_equal(moved, control_error_table(initial_error=0.1, seed=1))
    with pytest.raises(ValueError, match="qpos"):
        control_error_table(options={"qpos": start_1["qpos"][:-1]})

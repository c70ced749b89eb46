"""SB3's batch convention for ``predict``: one observation, or ``(n, *shape)`` from a vector env.

Shared by the policy objects (:mod:`~ias_gym.baselines.policies`,
:mod:`~ias_gym.baselines.expert`); numpy only, so that the light policy loader stays light.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ias_gym.errors import InputError


def batch_size(observation: Any, shape: tuple[int, ...] | None) -> int | None:
    """SB3's convention: ``None`` for one observation of ``shape``, ``n`` for a batch
    ``(n, *shape)`` from a vector env.

    Args:
        observation: what ``predict`` was given.
        shape: the env's (single) observation shape; ``None``: unknown, one observation.

    Raises:
        InputError: ``observation`` is neither of ``shape`` nor a batch of it.
    """
    obs_shape = np.shape(observation)
    if shape is None or obs_shape == shape:
        return None
    if len(obs_shape) == len(shape) + 1 and obs_shape[1:] == shape:
        return int(obs_shape[0])
    raise InputError(
        f"observation of shape {obs_shape} is neither one observation {shape} nor a batch "
        f"(n, *{shape}) from a vector env"
    )

"""Closed-loop tests that hold on any machine: the same rollout from nearby starts.

A closed-loop rollout (the controller or a trained policy acting on the simulation) is
chaotic: another CPU or BLAS changes the last bits of a step and the trajectories part. A
test that passes from the one start this machine computed may sit on a knife edge that
another machine falls off. :func:`perturbed_starts` gives a seed's own start and
``N_PERTURBED`` starts whose ``qpos`` differ from it by about ``PERTURBATION``, what another
machine does to a rollout; every test that runs the controller or a policy for more than a few
steps checks its property from each of them.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import gymnasium as gym
import numpy as np

#: Size of the perturbation of each qpos entry [m or rad]: another machine's last bits.
PERTURBATION = 1e-9
#: How many perturbed starts follow the nominal one.
N_PERTURBED = 5


def perturbed_starts(
    env: gym.Env[Any, Any], seed: int, n: int = N_PERTURBED, scale: float = PERTURBATION
) -> Iterator[dict[str, Any] | None]:
    """Reset options for ``env.reset(seed=seed, options=...)``: ``None`` (the seed's own
    start), then ``n`` starts with ``qpos`` perturbed by Gaussian noise of ``scale``.

    The env must accept ``options={"qpos": ..., "qvel": ...}`` (every IAS pen task does).
    """
    env.reset(seed=seed)
    data = env.unwrapped.data  # type: ignore[attr-defined]
    qpos, qvel = data.qpos.copy(), data.qvel.copy()
    rng = np.random.default_rng(seed)
    yield None
    for _ in range(n):
        yield {"qpos": qpos + rng.normal(0.0, scale, qpos.shape), "qvel": qvel.copy()}

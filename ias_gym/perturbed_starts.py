"""Nearby starts of a seeded episode: the seed's own MuJoCo state and starts whose ``qpos``
differ from it by 1e-9 (:func:`perturbed_starts`), to check that a closed-loop result is
not a knife edge of this machine's arithmetic; and the perturbation mode
(``$IAS_GYM_PERTURB_SEED``, :func:`perturb_seed`) in which the seed's own start moves too.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import gymnasium as gym
import numpy as np

from ias_gym.settings import seed_from_environment

#: Size of the perturbation of each qpos entry of a nearby start [m or rad]: another
#: machine's last bits (:func:`perturbed_starts`).
PERTURBATION = 1e-9
#: How many perturbed starts follow the nominal one.
N_PERTURBED = 5
#: Environment variable of the perturbation mode (:func:`perturb_seed`): when set to an
#: integer, :func:`perturbed_starts` moves the seed's own start too, as another machine would.
PERTURB_SEED_VAR = "IAS_GYM_PERTURB_SEED"
#: Most nearby starts after the first in the perturbation mode: its run is one more sample of
#: starts after the normal one (``make test-perturbed`` after ``make test``), not a second
#: sweep of as many.
PERTURB_MODE_NEARBY = 2


def perturb_seed() -> int | None:
    """The perturbation mode's seed: ``$IAS_GYM_PERTURB_SEED`` as an integer, None if unset
    or empty (the normal mode).

    Raises:
        InputError: the variable is set but is not an integer >= 0 (a numpy seed).
    """
    return seed_from_environment(PERTURB_SEED_VAR)


def perturbed_starts(
    env: gym.Env[Any, Any], seed: int, n: int = N_PERTURBED, scale: float = PERTURBATION
) -> Iterator[dict[str, Any] | None]:
    """Reset options for ``env.reset(seed=seed, options=...)``: ``None`` (the seed's own
    start), then ``n`` starts whose ``qpos`` differ from it by Gaussian noise of ``scale``.

    A closed-loop rollout is chaotic: another CPU or BLAS changes the last bits of a step and
    the trajectories part. A result that holds from the nominal start only may sit on a
    knife edge another machine falls off; the same result from these starts does not. The
    env must accept ``options={"qpos": ..., "qvel": ...}`` (every IAS pen and glove task).

    In the perturbation mode (``$IAS_GYM_PERTURB_SEED`` set: :func:`perturb_seed`) the first
    start is not the seed's own either: its ``qpos`` is moved by the same noise, drawn from a
    generator seeded by both seeds, so a result checked from these starts is checked from
    starts this machine has never computed, what another machine's last bits do; at most
    :data:`PERTURB_MODE_NEARBY` nearby starts follow it.
    """
    env.reset(seed=seed)
    data = env.unwrapped.data  # type: ignore[attr-defined]
    qpos, qvel = data.qpos.copy(), data.qvel.copy()
    mode = perturb_seed()
    if mode is None:
        yield None
    else:
        base = np.random.default_rng([mode, seed])
        qpos = qpos + base.normal(0.0, scale, qpos.shape)
        yield {"qpos": qpos.copy(), "qvel": qvel.copy()}
        n = min(n, PERTURB_MODE_NEARBY)
    rng = np.random.default_rng(seed)
    for _ in range(n):
        yield {"qpos": qpos + rng.normal(0.0, scale, qpos.shape), "qvel": qvel.copy()}


__all__ = [
    "N_PERTURBED",
    "PERTURBATION",
    "PERTURB_MODE_NEARBY",
    "PERTURB_SEED_VAR",
    "perturb_seed",
    "perturbed_starts",
]

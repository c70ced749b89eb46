"""tests/closed_loop.py: the nearby starts that closed-loop tests check their claims from."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.baselines.action_wrapper import GripTransformAction
from ias_gym.errors import InputError
from ias_gym.perturbed_starts import PERTURB_MODE_NEARBY, PERTURB_SEED_VAR, perturb_seed
from tests.closed_loop import N_PERTURBED, PERTURBATION, perturbed_starts


@pytest.mark.parametrize(
    "make",
    [
        lambda: gym.make("IAS-PenSlide-v0"),
        lambda: gym.make("IAS-PenRotate-v0"),
        lambda: GripTransformAction(gym.make("IAS-PenRotate-v0")),  # as test_controller uses it
    ],
    ids=["slide", "rotate", "rotate-wrapped"],
)
def test_perturbed_starts_are_the_seeds_start_moved_by_a_nanometre(
    make: Callable[[], gym.Env[Any, Any]], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The first start is the seed's own (``None``); the others differ from its qpos by
    less than 1e-7 (about ``PERTURBATION``) but do differ, from it and from one another,
    keep its qvel, and the env starts exactly from them."""
    monkeypatch.delenv(PERTURB_SEED_VAR, raising=False)
    env = make()
    data = env.unwrapped.data
    seed = 4
    env.reset(seed=seed)
    nominal_qpos, nominal_qvel = data.qpos.copy(), data.qvel.copy()
    starts = list(perturbed_starts(env, seed))
    assert len(starts) == 1 + N_PERTURBED and starts[0] is None
    env.reset(seed=seed, options=starts[0])  # None: the seed's own start, bit for bit
    np.testing.assert_array_equal(data.qpos, nominal_qpos)
    seen = [nominal_qpos]
    for options in starts[1:]:
        assert options is not None
        qpos, qvel = options["qpos"], options["qvel"]
        offset = np.abs(qpos - nominal_qpos)
        assert offset.max() < 1e-7 and offset.max() > PERTURBATION / 10
        assert not any(np.array_equal(qpos, other) for other in seen)
        seen.append(qpos)
        np.testing.assert_array_equal(qvel, nominal_qvel)
        env.reset(seed=seed, options=options)  # accepted, and the state is exactly it
        np.testing.assert_array_equal(data.qpos, qpos)
        np.testing.assert_array_equal(data.qvel, qvel)
        env.step(np.zeros(env.action_space.shape))  # and the simulation runs from it
        assert np.isfinite(data.qpos).all()
    # The same seed gives the same starts: a failing start can be rerun.
    again = list(perturbed_starts(env, seed))
    for a, b in zip(starts[1:], again[1:], strict=True):
        assert a is not None and b is not None
        np.testing.assert_array_equal(a["qpos"], b["qpos"])


def _qpos(starts: list[dict[str, Any] | None]) -> list[np.ndarray]:
    assert all(options is not None for options in starts)
    return [options["qpos"] for options in starts if options is not None]


def test_the_perturbation_mode_moves_the_seeds_own_start_too(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """With ``IAS_GYM_PERTURB_SEED`` set, every start is one this machine has not computed:
    the first too is moved by about ``PERTURBATION``, the same way for the same mode seed
    (a failure can be rerun) and another way for another; the others, at most
    ``PERTURB_MODE_NEARBY``, are moved from it."""
    env = gym.make("IAS-PenSlide-v0")
    seed = 4
    env.reset(seed=seed)
    nominal = env.unwrapped.data.qpos.copy()
    monkeypatch.setenv(PERTURB_SEED_VAR, "1234")
    assert perturb_seed() == 1234
    starts = _qpos(list(perturbed_starts(env, seed)))
    assert len(starts) == 1 + min(N_PERTURBED, PERTURB_MODE_NEARBY)
    assert len(list(perturbed_starts(env, seed, n=1))) == 2
    for qpos in starts:
        assert PERTURBATION / 10 < np.abs(qpos - nominal).max() < 1e-7
    for qpos in starts[1:]:
        assert PERTURBATION / 10 < np.abs(qpos - starts[0]).max() < 1e-7
    np.testing.assert_array_equal(starts[0], _qpos(list(perturbed_starts(env, seed, n=0)))[0])
    monkeypatch.setenv(PERTURB_SEED_VAR, "1235")
    assert not np.array_equal(starts[0], _qpos(list(perturbed_starts(env, seed, n=0)))[0])
    for unset in ("", " "):
        monkeypatch.setenv(PERTURB_SEED_VAR, unset)
        assert perturb_seed() is None
        assert next(perturbed_starts(env, seed)) is None
    for bad in ("x", "-1", "1.5"):
        monkeypatch.setenv(PERTURB_SEED_VAR, bad)
        with pytest.raises(InputError, match=PERTURB_SEED_VAR):
            perturb_seed()

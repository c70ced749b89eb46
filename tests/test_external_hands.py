"""What every hand read from another package shares: a missing package is one clear error
naming how to install it, and the registered largest tilt (``HandSpec.max_tilt``) is where
the Theorem-1 expert still succeeds, with no finger link on the pen.

Each hand's own checks are in tests/test_shadow_hand.py and tests/test_leap_hand.py; the
spec-driven checks of every hand (keyframe, shapes, contact ranges) in tests/test_hand3f.py."""

from __future__ import annotations

import importlib.util

import gymnasium as gym
import pytest

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.baselines.expert import ExpertPolicy
from ias_gym.errors import InputError
from ias_gym.rollout import rollout
from ias_gym.sim import external_hands, leap_hand
from ias_gym.sim.hands import get_hand
from tests.closed_loop import perturbed_starts

HANDS = {
    # hand: (env id, the module that looks the package up, the package, the fix it names, seed)
    "shadow": (
        "IAS-PenRotate-Shadow-v0",
        external_hands,
        "gymnasium_robotics",
        r"ias-gym\[hands\]",
        41,
    ),
    "leap": (
        "IAS-PenRotate-LEAP-v0",
        leap_hand,
        "mujoco_playground",
        r"pip install --no-deps playground==0\.2\.0",
        51,
    ),
}


@pytest.mark.parametrize("hand", sorted(HANDS))
def test_a_missing_package_says_how_to_install_it(
    hand: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    env_id, module, package, fix, _ = HANDS[hand]
    real = importlib.util.find_spec
    monkeypatch.setattr(
        module.importlib.util,
        "find_spec",
        lambda name, *a: None if name == package else real(name, *a),
    )
    with pytest.raises(InputError, match=fix):
        gym.make(env_id)


@pytest.mark.closed_loop
@pytest.mark.parametrize("frequency", [2.0, 12.0])
@pytest.mark.parametrize("hand", sorted(HANDS))
def test_the_expert_tracks_the_registered_largest_tilt(hand: str, frequency: float) -> None:
    """At ``HandSpec.max_tilt`` the expert succeeds from nearby starts at the slowest and the
    fastest frequency of the envelope, every internal-force problem solved, and no finger
    link touches the pen."""
    env_id, *_, seed = HANDS[hand]
    env = gym.make(env_id, frequency=frequency)
    assert env.unwrapped.config.amplitude == get_hand(hand).max_tilt
    policy = ExpertPolicy(env)
    physics = env.unwrapped.physics
    links: list[int] = []  # per step, over every start
    for start, options in enumerate(perturbed_starts(env, seed, n=2)):
        trajectory = rollout(
            env,
            policy,
            seed,
            reset_options=options,
            keep_infos=False,
            on_step=lambda *_: links.append(physics.n_link_contacts()),
        )
        assert trajectory.final_info["is_success"], (start, trajectory.final_info)
        assert policy.controller.infeasible_count == 0, start
    assert sum(links) == 0 and len(links) > 0

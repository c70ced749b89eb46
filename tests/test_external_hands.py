"""What every hand read from another package shares: a missing package is one clear error
naming how to install it, and the registered largest tilt (``HandSpec.max_tilt``) is where
the Theorem-1 expert still succeeds, with no finger link on the pen.

Each hand's own checks are in tests/test_shadow_hand.py and tests/test_leap_hand.py; the
spec-driven checks of every hand (keyframe, shapes, contact ranges) in tests/test_hand3f.py."""

from __future__ import annotations

import dataclasses
import importlib.util

import gymnasium as gym
import numpy as np
import pytest

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.baselines.expert import ExpertPolicy
from ias_gym.envs.pen_skill_env import PenSkillEnv
from ias_gym.envs.skill_reference import SkillReference
from ias_gym.errors import InputError
from ias_gym.rollout import rollout
from ias_gym.sim import external_hands, leap_hand
from ias_gym.sim.hands import get_hand
from ias_gym.skills.transfer_run import run_transfer, transfer_gains
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


def _opened(env: gym.Env, options: dict | None, finger: int, gap: float) -> dict:
    """The reset options of ``options``' start with ``finger``'s tip moved ``gap`` [m] off
    the pen along its contact normal (its three driven joints, through its tip Jacobian)."""
    env.reset(seed=0, options={**(options or {}), "skill": 0})
    physics = env.unwrapped.physics
    J = physics.fingertip_jacobians(physics.fingertip_contacts())
    rows = slice(3 * finger, 3 * finger + 3)
    dq = np.linalg.solve(J[rows, rows], np.array([-gap, 0.0, 0.0]))
    data = env.unwrapped.data
    qpos, qvel = data.qpos.copy(), data.qvel.copy()
    qpos[physics.hand_qpos_ids[rows]] += dq
    return {"qpos": qpos, "qvel": qvel}


@pytest.mark.closed_loop
@pytest.mark.parametrize("hand", sorted(HANDS))
def test_a_tip_opened_off_the_pen_closes_on_it_again(hand: str) -> None:
    """A still hold whose thumb starts 1.5 mm off the pen: executed with the transfer's
    gains, the thumb closes on the pen again (its joints' damping paid along the approach,
    ``ControllerGains.approach_speed``) and the pen is held to the end, from nearby starts.
    Without the approach the thumb crawls against its joints' damping (a few mm/s from the
    small force the internal-force problem gives it), the other fingers cannot hold the pen
    alone, and it drops."""
    dt, steps = 0.01, 101
    still = np.zeros((steps, 3))
    reference = SkillReference(
        dt=dt,
        position=still,
        velocity=still,
        acceleration=still,
        axis=np.tile([1.0, 0.0, 0.0], (steps, 1)),
        omega=still,
        alpha=still,
        margin=np.full(steps, 1.3),
        name="hold",
    )
    thumb = get_hand(hand).fingers.index("f2")
    env = PenSkillEnv(references=[reference], hand=hand, duration=1.0)
    gains = transfer_gains(hand)
    assert gains.approach_speed > 0
    for options in perturbed_starts(env, seed=0, n=2):
        opened = _opened(env, options, thumb, 0.0015)
        closing, _ = run_transfer(reference, hand, gains=gains, reset_options=opened, duration=1.0)
        assert closing.held_s == 1.0, options  # never dropped
        crawling, _ = run_transfer(
            reference,
            hand,
            gains=dataclasses.replace(gains, approach_speed=0.0),
            reset_options=opened,
            duration=1.0,
        )
        assert crawling.held_s < 1.0, options  # dropped
    env.close()

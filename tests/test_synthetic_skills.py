"""Synthetic skills: inside the hand's workspace, consistent derivatives, deterministic, and
executable by the expert on IAS-PenSkill-v0."""

from __future__ import annotations

import math

import numpy as np
import pytest
from closed_loop import perturbed_starts

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.baselines.expert import ExpertPolicy
from ias_gym.envs.pen_skill_env import PenSkillEnv
from ias_gym.errors import InputError
from ias_gym.rollout import rollout
from ias_gym.sim.hands import get_hand
from ias_gym.skills.synthetic import (
    SCALE_RANGE,
    SYNTHETIC_NAME,
    minimum_jerk,
    synthetic_references,
)
from ias_gym.skills.workspace import hand_workspace

MARGINS = [np.linspace(1.2, 1.8, 50), np.full(80, 1.5)]


def test_minimum_jerk_starts_and_ends_at_rest() -> None:
    s = np.linspace(0.0, 1.0, 1001)
    x = minimum_jerk(s)
    assert x[0] == 0.0 and x[-1] == pytest.approx(1.0)
    assert np.all(np.diff(x) >= 0)
    slope = np.gradient(x, s)
    assert abs(slope[0]) < 1e-3 and abs(slope[-1]) < 1e-3
    assert slope.max() == pytest.approx(1.875, rel=1e-3)  # the profile's peak speed
    assert minimum_jerk(np.array([-1.0, 2.0])).tolist() == [0.0, 1.0]  # clipped


def test_references_stay_in_the_workspace_and_start_at_rest() -> None:
    hand = "ias4f"
    ws = hand_workspace(hand)
    tilt_max = get_hand(hand).max_tilt  # PenRotate's tilt: synthetic turns are fast
    refs = synthetic_references(40, MARGINS, hand, 0.01, 3.0, seed=3)
    assert len(refs) == 40
    for ref in refs:
        assert ref.name == SYNTHETIC_NAME and ref.skill_id == -1 and ref.person == ""
        assert ref.length == 301 and ref.dt == 0.01
        # the filter smooths the corners a little: a hair beyond the waypoints' bounds
        assert np.linalg.norm(ref.position, axis=1).max() <= 1.05 * ws.reach
        tilt = np.degrees(np.arccos(np.clip(ref.axis @ np.array([1.0, 0, 0]), -1, 1)))
        assert tilt.max() <= 1.05 * math.degrees(tilt_max)
        assert np.linalg.norm(ref.position[0]) < 1e-4
        assert np.allclose(ref.axis[0], [1.0, 0.0, 0.0], atol=1e-3)
        assert 1.2 <= ref.margin.min() and ref.margin.max() <= 1.8
        assert SCALE_RANGE[0] <= ref.scale <= SCALE_RANGE[1]
        assert SCALE_RANGE[0] <= ref.scale_rotation <= SCALE_RANGE[1]
    # they cover the workspace: some go far, in every direction, and some turn far
    ends = np.array([np.abs(r.position).max(axis=0) for r in refs])
    assert np.all(ends.max(axis=0) > 0.5 * ws.reach)
    turns = [np.arccos(np.clip(r.axis @ [1.0, 0, 0], -1, 1)).max() for r in refs]
    assert max(turns) > 0.5 * tilt_max


def test_derivatives_match_the_motion() -> None:
    (ref,) = synthetic_references(1, MARGINS, seed=11)
    dt = ref.dt
    inner = slice(10, -10)
    velocity = np.gradient(ref.position, dt, axis=0)
    assert np.abs(velocity - ref.velocity)[inner].max() <= 0.05 * np.abs(ref.velocity).max()
    # omega x axis is the axis' rate of turn (the roll is free)
    axis_rate = np.gradient(ref.axis, dt, axis=0)
    rate = np.cross(ref.omega, ref.axis)
    assert np.abs(rate - axis_rate)[inner].max() <= 0.05 * np.abs(axis_rate).max()
    assert np.allclose(np.einsum("ij,ij->i", ref.omega, ref.axis), 0.0, atol=1e-9)


def test_the_draw_is_deterministic_in_its_seed() -> None:
    a = synthetic_references(3, MARGINS, seed=5)
    b = synthetic_references(3, MARGINS, seed=5)
    c = synthetic_references(3, MARGINS, seed=6)
    assert all(np.array_equal(x.position, y.position) for x, y in zip(a, b, strict=True))
    assert all(np.array_equal(x.axis, y.axis) for x, y in zip(a, b, strict=True))
    assert not np.array_equal(a[0].position, c[0].position)
    # the skills of one draw differ from each other
    assert not np.array_equal(a[0].position, a[1].position)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"count": -1}, ">= 0"),
        ({"margins": []}, "at least one margin"),
        ({"margins": [np.array([0.5, 1.5])]}, ">= 1"),
        ({"margins": [np.array([1.5, np.nan])]}, "finite"),
        ({"duration": 0.005}, "2 control periods"),
        ({"control_dt": 0.0}, "control_dt > 0"),
        ({"hand": "robonaut"}, "robonaut"),
    ],
)
def test_bad_input_is_refused(kwargs: dict[str, object], message: str) -> None:
    args: dict[str, object] = {"count": 2, "margins": MARGINS, **kwargs}
    with pytest.raises(InputError, match=message):
        synthetic_references(**args)  # type: ignore[arg-type]


@pytest.mark.closed_loop
def test_the_expert_executes_synthetic_skills() -> None:
    """From each skill's start and a nearby one: the pen is never dropped, and the expert
    tracks nearly all within the default tolerances (measured: every one, the largest RMS
    axis error 1.9 deg against 2.9)."""
    refs = synthetic_references(6, MARGINS, "ias4f", 0.01, 3.0, seed=21)
    env = PenSkillEnv(references=refs)
    policy = ExpertPolicy(env)
    successes: dict[int, int] = {}
    for i in range(len(refs)):
        for k, options in enumerate(perturbed_starts(env, 500 + i, n=1)):
            trajectory = rollout(
                env,
                policy,
                500 + i,
                reset_options={"skill": i, **(options or {})},
                keep_infos=False,
            )
            assert not trajectory.terminated  # the pen is never dropped
            successes[k] = successes.get(k, 0) + bool(trajectory.final_info["is_success"])
    env.close()
    assert all(n >= 5 for n in successes.values())

"""Synthetic skills: random pen motions inside a hand's workspace, to train skill execution.

A policy that executes stored skills (``IAS-PenSkill-v0``) reads the skill's reference in
its observation and must track it. Cloned from the executions of a few skill classes, it
tracks those and fails on a motion of another kind: it learned the classes, not tracking.
The teacher, Theorem 1's control law, tracks any reference the hand can carry, so training
can draw references of its own that cover the hand's workspace, as goal randomisation
covers the goals of in-hand reorientation (OpenAI et al. 2019, "Solving Rubik's Cube with a
robot hand"). The human skills stay in the training library; the synthetic ones are added
beside them.

A synthetic skill is a chain of minimum-jerk segments (Flash & Hogan 1985, the model of the
population's movements too) between random waypoints, every range the hand's or the
human's, none a skill's:

- waypoints of the pen centre uniform in the ball of the hand's reach, and of the axis'
  tilt and turn uniform in the disc of the hand's largest tilt at PenRotate's rates
  (``HandSpec.max_tilt``: a segment may turn the axis at up to 2.5 Hz, faster than a
  transferred skill, whose workspace tilts further but slower); each segment moves the
  centre, the axis or both, or holds still;
- segment durations uniform in :data:`SEGMENT_DURATION`: a back-and-forth of two such
  segments is a 0.5-2.5 Hz oscillation, the band of voluntary hand motion (Brooks 1990,
  "Telerobotic response requirements": 1-2 Hz for unexpected signals, 2-5 Hz for learned
  trajectories);
- the motion lasts a duration uniform in :data:`MOTION_SHARE` of the episode and then
  holds its last pose, as a demonstration does;
- the grasp margin is the margin series of a human skill drawn from the ``margins`` given
  (the training library's), stretched to the synthetic skill's length;
- the translation and rotation scales, which the env's observation carries but tracking
  does not need, uniform in :data:`SCALE_RANGE`, so that a policy cannot key on them.

The references are built by the same filter as a transferred skill's
(:func:`~ias_gym.skills.transfer.motion_reference`) and carry no tolerances (the env's
defaults). Skill id -1, name :data:`SYNTHETIC_NAME`, no person. An env on them::

    refs = synthetic_references(100, [np.full(10, 1.5)], hand="ias4f")
    env = gym.make("IAS-PenSkill-v0", references=refs)

``train/pen_skill_bc.py --synthetic-skills N`` adds N of them to the human skills it trains
on; docs/results-learning.md has what they change.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from ias_gym.envs.skill_reference import SkillReference
from ias_gym.errors import InputError
from ias_gym.sim.hands import get_hand
from ias_gym.skills.transfer import FloatArray, motion_reference
from ias_gym.skills.workspace import HandWorkspace, hand_workspace

#: The name of every synthetic skill.
SYNTHETIC_NAME = "synthetic"
#: Duration of one minimum-jerk segment [s] (uniform).
SEGMENT_DURATION = (0.2, 1.0)
#: The motion lasts this share of the episode, then the pose is held [-] (uniform).
MOTION_SHARE = (0.5, 1.0)
#: A segment holds still, moves the centre only, the axis only, or both (probabilities).
SEGMENT_KINDS = {"hold": 0.15, "translate": 0.25, "rotate": 0.25, "both": 0.35}
#: The translation and rotation scales carried in the observation [-] (uniform).
SCALE_RANGE = (0.25, 1.0)


def minimum_jerk(s: FloatArray) -> FloatArray:
    """The minimum-jerk profile ``10 s^3 - 15 s^4 + 6 s^5`` of normalised time ``s`` in [0, 1]."""
    s = np.clip(s, 0.0, 1.0)
    return np.asarray(s**3 * (10.0 - 15.0 * s + 6.0 * s * s))


def _in_ball(rng: np.random.Generator, radius: float, dim: int) -> FloatArray:
    """A point uniform in the ``dim``-ball of ``radius``."""
    direction = rng.normal(size=dim)
    direction /= np.linalg.norm(direction)
    return np.asarray(direction * radius * rng.uniform() ** (1.0 / dim))


def synthetic_motion(
    rng: np.random.Generator, workspace: HandWorkspace, samples: int, dt: float
) -> tuple[FloatArray, FloatArray]:
    """One random motion: ``(samples, 3)`` centre positions [m] and ``(samples, 2)`` tilt and
    turn [rad], starting at rest at the origin (module docstring)."""
    t = np.arange(samples) * dt
    end = rng.uniform(*MOTION_SHARE) * t[-1]
    kinds, weights = list(SEGMENT_KINDS), np.array(list(SEGMENT_KINDS.values()))
    weights = weights / weights.sum()
    position, angles = np.zeros((samples, 3)), np.zeros((samples, 2))
    here, turn = np.zeros(3), np.zeros(2)
    start = 0.0
    while start < end:
        length = rng.uniform(*SEGMENT_DURATION)
        kind = kinds[rng.choice(len(kinds), p=weights)]
        goal = _in_ball(rng, workspace.reach, 3) if kind in ("translate", "both") else here
        goal_turn = _in_ball(rng, workspace.tilt, 2) if kind in ("rotate", "both") else turn
        after = t >= start
        s = minimum_jerk(np.asarray((t[after] - start) / length, dtype=float))[:, None]
        position[after] = here + s * (goal - here)
        angles[after] = turn + s * (goal_turn - turn)
        here, turn, start = goal, goal_turn, start + length
    return position, angles


def synthetic_references(
    count: int,
    margins: Sequence[FloatArray],
    hand: str = "ias4f",
    control_dt: float = 0.01,
    duration: float = 3.0,
    seed: int = 0,
) -> list[SkillReference]:
    """``count`` synthetic skills for ``hand`` (module docstring), deterministic in ``seed``.

    Args:
        count: how many (>= 0).
        margins: grasp-margin series to draw each skill's margin from (e.g. the training
            library's references' ``margin``); at least one, each finite and >= 1.
        hand: the target hand (its workspace).
        control_dt: the env's control period [s].
        duration: the episode's length [s] (the references span it).
        seed: the draws' seed.

    Raises:
        InputError: ``count`` < 0, no margins or one out of range, ``duration`` shorter
            than two control periods, or an unknown hand.
    """
    if count < 0:
        raise InputError(f"the number of synthetic skills must be >= 0, got {count}")
    if not margins:
        raise InputError("synthetic skills need at least one margin series to draw from")
    series = [np.asarray(m, dtype=float) for m in margins]
    if any(m.ndim != 1 or len(m) < 1 or not np.all(np.isfinite(m) & (m >= 1.0)) for m in series):
        raise InputError("every margin series must be 1-D, finite and >= 1")
    if not (math.isfinite(control_dt) and control_dt > 0 and math.isfinite(duration)):
        raise InputError(f"synthetic skills need a finite control_dt > 0, got {control_dt}")
    samples = math.floor(duration / control_dt + 1e-9) + 1
    if samples < 2:
        raise InputError(
            f"synthetic skills need a duration of >= 2 control periods, got {duration} s "
            f"at {control_dt} s"
        )
    workspace = dataclasses.replace(hand_workspace(hand), tilt=get_hand(hand).max_tilt)
    rng = np.random.default_rng(seed)
    grid = np.linspace(0.0, 1.0, samples)
    out = []
    for _ in range(count):
        position, angles = synthetic_motion(rng, workspace, samples, control_dt)
        template = series[rng.integers(len(series))]
        margin = np.interp(grid, np.linspace(0.0, 1.0, len(template)), template)
        out.append(
            motion_reference(
                position,
                angles,
                margin,
                control_dt,
                name=SYNTHETIC_NAME,
                scale=float(rng.uniform(*SCALE_RANGE)),
                scale_rotation=float(rng.uniform(*SCALE_RANGE)),
            )
        )
    return out


__all__ = [
    "MOTION_SHARE",
    "SCALE_RANGE",
    "SEGMENT_DURATION",
    "SEGMENT_KINDS",
    "SYNTHETIC_NAME",
    "minimum_jerk",
    "synthetic_motion",
    "synthetic_references",
]

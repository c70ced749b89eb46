"""Synthetic pinches and skills with closed-form margins, shared by the transfer tests."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np

from ias_gym.grasp.wrench_matrix import wrench_matrix
from ias_gym.sim.pen import matrix_to_rpy, rpy_to_matrix
from ias_gym.skills.skill import Demonstration, Skill, SkillModel

#: The friction coefficient of the closed forms [-].
MU = 0.25
#: The sample period of a synthetic skill [s].
DT = 0.01


def random_contacts(rng: np.random.Generator, per: int) -> tuple[np.ndarray, np.ndarray]:
    """Three contacts of ``per`` (3 or 4) intensities: a random particular part (any signs,
    any directions) and a random squeeze pressing every contact, ``(c_p, c_h)``; with 4, small
    torsions. Some hold at some scale of the squeeze, some at none."""
    c_p = rng.normal(size=3 * per)
    c_h = 0.12 * rng.normal(size=3 * per)
    c_h[::per] = rng.uniform(0.3, 2.0, 3)
    if per == 4:
        c_p[3::4] *= 0.01
        c_h[3::4] *= 0.005
    return c_p, c_h


def antipodal_pinch(weight: float, squeeze: float) -> tuple[np.ndarray, np.ndarray]:
    """Two point contacts pinching an object along x, holding its weight by friction.

    Contact 1 at (-r, 0, 0) pushes +x, contact 2 at (+r, 0, 0) pushes -x; t1 = +y, t2 = +z.
    Returns ``(c_p, c_h)``: c_p = W+ [0, weight, 0, 0, 0, 0], c_h = the squeeze.
    """
    r = 0.01
    points = np.array([[-r, 0.0, 0.0], [r, 0.0, 0.0]])
    frames = np.array(
        [
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        ]
    )
    W = wrench_matrix(points, frames)
    c_p = np.linalg.pinv(W) @ np.array([0.0, weight, 0.0, 0.0, 0.0, 0.0])
    c_h = np.array([squeeze, 0.0, 0.0, squeeze, 0.0, 0.0])
    assert np.allclose(W @ c_h, 0.0)
    return c_p, c_h


def synthetic_skill(
    *,
    lift: float = 0.02,
    tilt: float = 0.15,
    heading: float = 0.0,
    squeeze: float = 4.0,
    grasp_at: float = 0.3,
    duration: float = 2.5,
    touching: bool = True,
    success: bool = True,
    name: str = "synthetic-lift-tilt",
    sliding_from: float | None = None,
) -> Skill:
    """A pinch that grasps at ``grasp_at``, then lifts the pen by ``lift`` [m] and tilts it
    by ``tilt`` [rad] along smooth ramps; its margin is ``2 mu squeeze / 1 N`` throughout.
    ``sliding_from`` schedules the first contact to slide from then on [s]."""
    t = np.arange(0.0, duration + 1e-9, DT)
    T = len(t)
    u = np.clip((t - grasp_at) / 1.0, 0.0, 1.0)
    ramp = u * u * (3 - 2 * u)  # smoothstep 0 -> 1 over one second
    pos = np.zeros((T, 3))
    pos[:, 1] = lift * ramp
    pos[:, 0] = 0.2 * lift * ramp
    rpy = np.zeros((T, 3))
    rpy[:, 0] = 2.0 * ramp  # the roll about the pen's own axis must not matter
    rpy[:, 2] = tilt * np.sin(np.pi * ramp)
    # the whole demonstration turned about the vertical by `heading`
    c, s = math.cos(heading), math.sin(heading)
    turn = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # R_y(heading)
    pos = pos @ turn.T
    rpy = np.array([matrix_to_rpy(turn @ rpy_to_matrix(r)) for r in rpy])
    c_p, c_h = antipodal_pinch(1.0, squeeze)
    on = np.tile([touching, touching], (T, 1)) & (t >= grasp_at)[:, None]
    c_h_rows = np.where(on.all(1)[:, None], c_h, np.nan)
    model = SkillModel(
        time=t,
        touching=on,
        sliding=np.zeros((T, 2), dtype=bool)
        if sliding_from is None
        else np.stack([t >= sliding_from, np.zeros(T, dtype=bool)], axis=1),
        pen_position=pos,
        pen_rpy=rpy,
        pen_velocity=np.gradient(pos, DT, axis=0),
        pen_omega=np.zeros((T, 3)),
        c=np.tile(c_p, (T, 1)) + np.nan_to_num(c_h_rows),
        c_h=c_h_rows,
        f_ext=np.tile([0.0, 1.0, 0.0, 0.0, 0.0, 0.0], (T, 1)),
        f_int=np.where(on.all(1), squeeze, np.nan)[:, None],
    )
    demo = Demonstration(
        observations=np.zeros((T, 2)),
        actions=np.zeros((T - 1, 1)),
        rewards=np.zeros(T - 1),
        terminations=np.zeros(T - 1, dtype=bool),
        truncations=np.zeros(T - 1, dtype=bool),
    )
    skill = Skill(
        name=name,
        task="IAS-GloveGrasp-v0",
        source="test",
        demonstration=demo,
        model=model,
        is_success=success,
        person_id="synthetic",
    )
    skill.validate()
    return skill


def transfer_cli(*args: str) -> subprocess.CompletedProcess[str]:
    """``ias-gym skills transfer ARGS`` in a fresh interpreter, its output captured."""
    return subprocess.run(
        [sys.executable, "-m", "ias_gym.cli", "skills", "transfer", *args],
        capture_output=True,
        text=True,
        check=False,
    )

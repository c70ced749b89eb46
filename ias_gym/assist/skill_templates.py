"""A glove skill's stored model as the analytic assistant reads it: its template.

:func:`load_templates` reads every glove skill of a library, aligns its demonstrations at
their skill start and averages them into a :class:`SkillTemplate`: the joint angles, the pen's
height, the grasp margin and the pinch force the assistant compares the operator with.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ias_gym.envs.glove_world import OBSERVATION
from ias_gym.errors import InputError
from ias_gym.glove.hand import N_JOINTS
from ias_gym.glove.skills import SKILLS
from ias_gym.skills.db import SkillDB
from ias_gym.skills.transfer import demonstrated_margin, shipped_skill_db, skill_start_index

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SkillTemplate:
    """One skill's stored model as the assistant uses it.

    Attributes:
        name: the skill.
        time: ``(T,)`` episode time of the template [s], its skill starting at ``start``.
        theta: ``(T, 10)`` the mean joint angles of the demonstrations [rad].
        start: the template's skill start [s].
        margin: the median grasp margin of the demonstrations from their skill start [-].
        height: ``(T,)`` the mean height of the pen above its start [m] (the object
            trajectory's vertical part).
        force: the median pinch force of the demonstrations from their skill start (sum
            of the pads' normal intensities) [N].
    """

    name: str
    time: FloatArray
    theta: FloatArray
    start: float
    margin: float
    height: FloatArray
    force: float

    def height_at(self, tau: float) -> float:
        """The pen's height above its start at template time ``tau`` [m]."""
        return float(np.interp(tau, self.time, self.height))

    def at(self, tau: float) -> FloatArray:
        """``(10,)`` joint angles at template time ``tau`` [s] (linear interpolation, held
        at the ends)."""
        out: FloatArray = np.array(
            [np.interp(tau, self.time, self.theta[:, j]) for j in range(N_JOINTS)]
        )
        return out


def load_templates(db_path: str | Path | None = None) -> dict[str, SkillTemplate]:
    """The templates of every glove skill in a library (default: the shipped one).

    Each skill's demonstrations are aligned at their skill start and averaged.

    Args:
        db_path: a skill database (read-only).

    Returns:
        ``{skill name: template}`` for the glove skills the library holds.

    Raises:
        InputError: the file does not exist, or holds no glove skill.
    """
    path = Path(db_path) if db_path is not None else shipped_skill_db()
    if not path.is_file():
        raise InputError(f"skill library {path} does not exist (give an existing --db)")
    groups: dict[str, list[tuple[FloatArray, FloatArray, float, float, FloatArray, float]]] = {}
    with SkillDB(path, readonly=True) as db:
        for skill_id in db.ids():
            skill = db.get(skill_id)
            if skill.name not in SKILLS or skill.person_id is None:
                continue
            model = skill.model
            k = skill_start_index(skill)
            margins = demonstrated_margin(skill)[k:]
            finite = margins[np.isfinite(margins)]
            margin = float(np.median(np.minimum(finite, 10.0))) if finite.size else 1.2
            start = float(model.time[k])  # the record's own motion start (or its grasp's)
            obs = np.asarray(skill.demonstration.observations, dtype=np.float64)
            per = model.c.shape[1] // model.touching.shape[1]
            normal = np.nan_to_num(np.asarray(model.c)[:, ::per]).sum(axis=1)
            groups.setdefault(skill.name, []).append(
                (
                    np.asarray(model.time, dtype=np.float64),
                    obs[:, OBSERVATION["joint_angles"]],
                    start,
                    margin,
                    obs[:, OBSERVATION["pen_position"]][:, 2],  # the pen's height [m]
                    float(np.median(normal[k:])),
                )
            )
    if not groups:
        raise InputError(f"skill library {path} holds no glove skill ({', '.join(SKILLS)})")
    out = {}
    for name, demos in groups.items():
        start = float(np.mean([d[2] for d in demos]))
        time = demos[0][0]
        # every demonstration shifted so that its skill starts at the mean start
        theta = np.mean(
            [
                np.stack(
                    [np.interp(time + d[2] - start, d[0], d[1][:, j]) for j in range(N_JOINTS)], 1
                )
                for d in demos
            ],
            axis=0,
        )
        height = np.mean([np.interp(time + d[2] - start, d[0], d[4]) for d in demos], axis=0)
        margin = float(np.median([d[3] for d in demos]))
        force = float(np.median([d[5] for d in demos]))
        out[name] = SkillTemplate(name, time, theta, start, margin, height, force)
    return out

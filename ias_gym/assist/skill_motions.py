"""The library's skill motions the assistant completes (:class:`SkillMotion`,
:func:`load_motions`): each glove skill's mean joint trajectory from its demonstrations'
skill start, less the holding skill's (:data:`HOLD_SKILL`), on the joints it moves.
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
from ias_gym.skills.transfer import shipped_skill_db, skill_start_index

FloatArray = NDArray[np.float64]

#: A skill's template moves a joint if its range over the motion, beyond the holding
#: skill's, exceeds this [rad] (under a third of the smallest, the fast see-saw's 0.1 rad).
MOVING_JOINT = 0.03
#: The skill that holds the pen still after the lift: what the others share.
HOLD_SKILL = "lift_hold"


@dataclass(frozen=True)
class SkillMotion:
    """How one skill moves the joints, from its demonstrations.

    Attributes:
        name: the skill.
        tau: ``(T,)`` time since the skill's start [s] (the library's mean person).
        delta: ``(T, J)`` the mean joint angles less those at the start [rad], on ``joints``.
        joints: the joints the skill moves (indices into ``JOINT_NAMES``).
        amplitude_range: the smallest and largest amplitude of a demonstration relative to
            the mean (least squares on ``joints``) [-]: how much persons differ.
    """

    name: str
    tau: FloatArray
    delta: FloatArray
    joints: NDArray[np.int64]
    amplitude_range: tuple[float, float]

    @property
    def principal(self) -> int:
        """The position in :attr:`joints` of the joint the skill moves most."""
        return int(np.argmax(np.ptp(self.delta, axis=0)))

    def at(self, tau: FloatArray) -> FloatArray:
        """``(len(tau), J)`` the motion at times ``tau`` (0 before the start, held after)."""
        return np.stack(
            [np.interp(tau, self.tau, self.delta[:, j], left=0.0) for j in range(len(self.joints))],
            axis=-1,
        )


def load_motions(db_path: str | Path | None = None) -> dict[str, SkillMotion]:
    """Every glove skill's :class:`SkillMotion` in a library (default: the shipped one): the
    mean of its demonstrations from their skill start, less the holding skill's
    (:data:`HOLD_SKILL`); skills that move no joint beyond it are left out.

    Raises:
        InputError: the file does not exist.
    """
    path = Path(db_path) if db_path is not None else shipped_skill_db()
    if not path.is_file():
        raise InputError(f"skill library {path} does not exist (give an existing --db)")
    groups: dict[str, list[tuple[FloatArray, FloatArray]]] = {}
    with SkillDB(path, readonly=True) as db:
        for skill_id in db.ids():
            skill = db.get(skill_id)
            if skill.person_id is None or skill.name not in SKILLS:
                continue
            k = skill_start_index(skill)
            time = np.asarray(skill.model.time, dtype=np.float64)
            obs = np.asarray(skill.demonstration.observations, dtype=np.float64)
            theta = obs[: len(time), OBSERVATION["joint_angles"]]
            groups.setdefault(skill.name, []).append((time[k:] - time[k], theta[k:] - theta[k]))
    means: dict[str, tuple[FloatArray, FloatArray]] = {}
    resampled: dict[str, FloatArray] = {}  # (D, T, 10) each demonstration on the mean's grid
    for name, demos in groups.items():
        end = min(float(t[-1]) for t, _ in demos)
        tau = np.arange(0.0, end, 0.01)
        each = np.array(
            [np.stack([np.interp(tau, t, d[:, j]) for j in range(N_JOINTS)], 1) for t, d in demos]
        )
        means[name], resampled[name] = (tau, each.mean(axis=0)), each
    # What every skill shares after its start (the grip settling, the lift's end) is the
    # holding skill's motion; each skill's own motion is what it does beyond that.
    shared = means.get(HOLD_SKILL)
    out = {}
    for name, (tau, mean) in means.items():
        base = np.zeros_like(mean)
        if shared is not None:
            base = np.stack(
                [np.interp(tau, shared[0], shared[1][:, j]) for j in range(N_JOINTS)], 1
            )
        joints = np.flatnonzero(np.ptp(mean - base, axis=0) > MOVING_JOINT)
        if not joints.size:
            continue
        m = (mean - base)[:, joints]
        amps = [float(((d - base)[:, joints] * m).sum() / (m * m).sum()) for d in resampled[name]]
        out[name] = SkillMotion(name, tau, m, joints, (min(amps), max(amps)))
    return out

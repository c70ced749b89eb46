"""Both pads on the pen: the pinch's contact schedule kept from the force display.

Every glove skill of the library pinches the pen between the index's and the thumb's pads
from the close to the end. The force display (the observation's ``feedback_torques``) says
which pad touches the pen: a finger's joints feel a torque exactly when the finger presses
on something (in the pinch, its pad on the pen). An operator whose pinch falls short (a weak
grip, a calibration that reads the fingers more open than they are) brings one pad to the
pen and never the other, or lets it slip off, and the pen falls in the lift.
:class:`PadKeeper` closes the finger whose pad is off the pen while the other's is on, once
that has lasted longer than the library's pads ever took to meet, counted from no earlier
than the first time a demonstrator's pad came to the pen, and keeps what it added: it never
opens a grip. Before that a pad on the pen is resting on it (a thumb that touches the pen
from the start), not pinching.

What it reads of the library (:func:`pinch_closing`): each finger's closing direction (the
demonstrations' joint change from the session's start to that pad's first contact, of the
operator's targets or, in a recording without them, the hand's joint angles, mean
over the demonstrations, largest component 1), how long a demonstrator's first pad was on
the pen alone before the other met it (the longest, over the demonstrations) and when the
first pad of any demonstration came to the pen (:func:`pad_arrivals`: a pad on the pen from
the session's first step rests on it and has not come to it, so one such demonstrator
moves neither statistic). Its rate is
:attr:`~ias_gym.assist.motion_completion.AssistParams.pad_close_rate`, fitted on
development persons (``train/fit_assist_field.py --field pad_close_rate``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ias_gym.assist.stream import THETA_INFO
from ias_gym.envs.glove_world import OBSERVATION
from ias_gym.errors import InputError
from ias_gym.glove.device import ACTUATED_JOINTS
from ias_gym.glove.hand import JOINT_NAMES, N_JOINTS
from ias_gym.skills.db import SkillDB

FloatArray = NDArray[np.float64]

#: The pinching fingers, and the force display's columns (``ACTUATED_JOINTS``) of each.
PINCH_FINGERS: tuple[str, ...] = ("index", "thumb")
TORQUE_COLUMNS: dict[str, tuple[int, ...]] = {
    f: tuple(i for i, name in enumerate(ACTUATED_JOINTS) if name.startswith(f))
    for f in PINCH_FINGERS
}
#: ... and each finger's joints among the hand's (``JOINT_NAMES``), by index.
PINCH_JOINTS_OF: dict[str, tuple[int, ...]] = {
    f: tuple(i for i, name in enumerate(JOINT_NAMES) if name.startswith(f)) for f in PINCH_FINGERS
}


@dataclass(frozen=True)
class PinchClosing:
    """What the library says of its pinches (:func:`pinch_closing`).

    Attributes:
        directions: each finger's ``(10,)`` closing direction [-] (its joints only, the
            largest component 1).
        meet_s: the longest time a demonstration's first pad was on the pen before the other
            touched it too [s].
        touch_from_s: the earliest episode time at which a demonstration's first pad came to
            the pen [s] (:func:`pad_arrivals`: a pad resting on it from the start has not).
    """

    directions: dict[str, FloatArray]
    meet_s: float
    touch_from_s: float


def _on(torques: FloatArray) -> dict[str, NDArray[np.bool_]]:
    """Per finger, whether its pad touches (any of its display torques nonzero), per row."""
    t = np.atleast_2d(np.abs(torques))
    return {f: np.any(t[:, list(cols)] > 0.0, axis=1) for f, cols in TORQUE_COLUMNS.items()}


def pad_arrivals(on: dict[str, NDArray[np.bool_]]) -> dict[str, int]:
    """The step at which each finger's pad came to the pen in one session (``on``: per
    finger, whether its pad touches, per step; :func:`_on`): the first step on the pen after
    one off it. A pad on the pen from the session's first step rests there; it has not come
    to the pen until it left it and came back (a finger that never came is left out)."""
    out = {}
    for f, touching in on.items():
        came = np.flatnonzero(touching[1:] & ~touching[:-1])
        if came.size:
            out[f] = int(came[0]) + 1
    return out


def pinch_closing(db_path: str | Path) -> PinchClosing:
    """The library's :class:`PinchClosing`, from its glove sessions' operator targets and
    force display.

    Raises:
        InputError: the file does not exist, or no glove session in it ever pinches.
    """
    path = Path(db_path)
    if not path.is_file():
        raise InputError(f"skill library {path} does not exist (give an existing --db)")
    steps: dict[str, list[FloatArray]] = {f: [] for f in PINCH_FINGERS}
    meets: list[float] = []
    touches: list[float] = []
    with SkillDB(path, readonly=True) as db:
        for skill_id in db.ids():
            skill = db.get(skill_id)
            demo = skill.demonstration
            if skill.person_id is None:
                continue
            obs = np.asarray(demo.observations, dtype=np.float64)
            targets = demo.infos.get(THETA_INFO) if demo.infos else None
            # the operator's targets, or in a recording without them the hand's angles
            raw = obs[:, OBSERVATION["joint_angles"]] if targets is None else targets
            theta = np.asarray(raw, dtype=np.float64)[: len(obs)]
            on = _on(obs[: len(theta), OBSERVATION["feedback_torques"]])
            time = obs[: len(theta), OBSERVATION["time"].start]
            arrived = pad_arrivals(on)
            if not arrived:
                continue
            first = min(arrived.values())
            both = np.flatnonzero(on["index"] & on["thumb"])
            both = both[both >= first]
            if not both.size:  # no pinch
                continue
            touches.append(float(time[first]))
            meets.append(float(time[both[0]] - time[first]))
            for f, k in arrived.items():
                change = np.zeros(N_JOINTS)
                joints = list(PINCH_JOINTS_OF[f])
                change[joints] = theta[k, joints] - theta[0, joints]
                steps[f].append(change)
    if not meets or not all(steps.values()):
        raise InputError(f"skill library {path} holds no glove session that pinches the pen")
    directions = {}
    for f, changes in steps.items():
        mean = np.mean(changes, axis=0)
        directions[f] = mean / np.max(np.abs(mean))
    return PinchClosing(directions, max(meets), min(touches))


class PadKeeper:
    """Closes the finger whose pad is off the pen while the other's is on (module docstring).

    Args:
        closing: the library's :class:`PinchClosing`.
        rate: how fast the finger closes [rad/s] (of its closing direction's largest
            component).
        limit: the most it adds to a finger [rad] (the env's ``action_scale``).
        control_dt: the env's step [s].
    """

    def __init__(self, closing: PinchClosing, rate: float, limit: float, control_dt: float) -> None:
        self.closing = closing
        self.rate = float(rate)
        self.limit = float(limit)
        self.dt = float(control_dt)
        self.reset()

    def reset(self) -> None:
        """Start a session."""
        self.added = dict.fromkeys(PINCH_FINGERS, 0.0)  # [rad] along each finger's direction
        self._alone = 0.0  # how long one pad has been on the pen alone [s]

    def update(self, torques: FloatArray, t: float) -> FloatArray:
        """The ``(10,)`` joint offset [rad] after a step whose force display was
        ``torques`` (the observation's ``feedback_torques``), at episode time ``t`` [s]."""
        on = {f: bool(v[0]) for f, v in _on(np.asarray(torques, dtype=np.float64)).items()}
        # one pad alone counts from the library's first touch on (before, it rests on the pen)
        alone = on["index"] != on["thumb"] and t >= self.closing.touch_from_s
        self._alone = self._alone + self.dt if alone else 0.0
        if self._alone > self.closing.meet_s:
            off = "thumb" if on["index"] else "index"
            self.added[off] = min(self.added[off] + self.rate * self.dt, self.limit)
        return sum(
            (self.added[f] * self.closing.directions[f] for f in PINCH_FINGERS), np.zeros(N_JOINTS)
        )

"""The part of a hand's workspace a transferred skill is scaled into (:class:`HandWorkspace`).

Measured per hand by ``train/hand_reach.py`` and carried by its ``HandSpec``
(:mod:`ias_gym.sim.hands`): the largest tilt of the pen's axis, its fastest turn, the
fastest move of its centre, and how far the hand carries the centre each way along the axes
and diagonals of the pen's start frame at a few shares of the tilt. :func:`workspace_scales`
fits a motion into it with two scales (docs/transfer.md, "Workspace scaling").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ias_gym.sim import hands

FloatArray = NDArray[np.float64]

__all__ = [
    "TRANSLATION_SHARE",
    "HandWorkspace",
    "hand_names",
    "hand_workspace",
    "workspace_scales",
]


@dataclass(frozen=True)
class HandWorkspace:
    """The part of a hand's workspace a transferred skill is scaled into.

    Attributes:
        reach: how far the hand moves the held pen's centre in any direction [m]: the ball
            of synthetic motions (:mod:`ias_gym.skills.synthetic`), and of a transfer
            where ``axes`` is None.
        tilt: the largest rotation of the pen's axis the expert handles [rad].
        axes: how far the expert carries the pen's centre while tilting it by up to each of
            ``tilt_shares`` of ``tilt`` (``HandSpec.reach_by_tilt``) [m]: one value per
            direction of :data:`ias_gym.sim.hands.REACH_DIRECTIONS` (both ways along x, the
            pen's heading, y, up, and z, lateral, then the diagonals), or one per axis for
            both ways and no diagonals; None: ``reach`` every way.
        tilt_shares: the tilts of ``axes``, as shares of ``tilt`` [-], increasing.
        tilt_rate: the fastest the expert turns the pen's axis [rad/s].
        speed: the fastest the expert moves the pen's centre [m/s].
    """

    reach: float
    tilt: float
    axes: tuple[tuple[float, ...], ...] | None = None
    tilt_shares: tuple[float, ...] = hands.REACH_TILT_SHARES
    tilt_rate: float = math.inf
    speed: float = math.inf

    def limits(self, turn: float = math.inf) -> tuple[float, ...]:
        """The largest excursion of the pen's centre per probed direction (``axes``' order)
        [m] for a motion that turns the pen's axis by at most
        ``turn`` [rad]: measured at the least probed tilt not below it (the reach shrinks as
        the tilt grows)."""
        if self.axes is None:
            return (self.reach, self.reach, self.reach)
        for share, axes in zip(self.tilt_shares, self.axes, strict=True):
            if turn <= share * self.tilt * (1 + 1e-9):
                return axes
        return self.axes[-1]

    def describe_motion(self) -> str:
        """The tilt, its rate and the speed for people: ``tilts the pen up to 22.9 deg at up
        to 90 deg/s, moves it up to 25 mm/s``."""
        rate = math.degrees(self.tilt_rate)
        text = f"tilts the pen up to {math.degrees(self.tilt):.1f} deg"
        text += f" at up to {rate:.0f} deg/s" if math.isfinite(rate) else ""
        speed = 1000 * self.speed
        return text + (f", moves it up to {speed:.0f} mm/s" if math.isfinite(speed) else "")

    def describe_reach(self, turn: float = math.inf) -> str:
        """The reach each way along the axes at ``turn`` [rad] for people (the diagonals are
        in ``axes``): ``carries it +x/-x/+y/-y/+z/-z 14/10/14/14/10/12 mm``."""
        limits = self.limits(turn)
        names = "x/y/z" if len(limits) == 3 else "/".join(hands.REACH_DIRECTIONS[:6])
        return f"carries it {names} {'/'.join(f'{1000 * v:.0f}' for v in limits[:6])} mm"

    def translation_scale(self, displacement: FloatArray, turn: float = math.inf) -> float:
        """The one scale that keeps a ``(T, 3)`` displacement [m] within the reach
        (:meth:`limits` at the motion's ``turn``): its excursion each way along each axis
        within that limit, its length within the largest, and, where the diagonals were
        measured, its part in each plane of two axes within the reach at its direction
        (linear in the angle between the axis and the diagonal of its quadrant). One scale
        for the three axes keeps the motion's direction."""
        limits = self.limits(turn)
        d = np.asarray(displacement, dtype=float)
        ratios = []
        length = float(np.max(np.linalg.norm(d, axis=1)))
        if length > 0:
            ratios.append(max(limits) / length)
        if len(limits) == 3:  # the same reach both ways, no diagonals
            peaks = np.abs(d).max(axis=0)
            ratios += [limits[a] / peaks[a] for a in range(3) if peaks[a] > 0]
            return float(min([1.0, *ratios]))
        for a in range(3):
            for way, peak in enumerate((d[:, a].max(), -d[:, a].min())):
                if peak > 0:
                    ratios.append(limits[2 * a + way] / peak)
        for p, (a, b) in enumerate(hands.REACH_PLANES):
            r = np.hypot(d[:, a], d[:, b])
            moved = r > 0
            if not moved.any():
                continue
            da, db = d[moved, a], d[moved, b]
            way_a, way_b = (da < 0).astype(int), (db < 0).astype(int)
            along_a = np.take(limits, 2 * a + way_a)
            along_b = np.take(limits, 2 * b + way_b)
            diagonal = np.take(limits, 6 + 4 * p + 2 * way_a + way_b)
            angle = np.arctan2(np.abs(db), np.abs(da)) / (math.pi / 4)  # 0 .. 2
            allowed = np.where(
                angle <= 1,
                along_a + angle * (diagonal - along_a),
                diagonal + (angle - 1) * (along_b - diagonal),
            )
            ratios.append(float(np.min(allowed / r[moved])))
        return float(min([1.0, *ratios]))


#: Synthetic motions stay in a ball of this fraction of the tips' reach along the pen
#: (measured with the pen at rest; the tips must still hold the pen at the far end of a
#: translation, tilted).
TRANSLATION_SHARE = 0.3


def hand_names() -> list[str]:
    """The robot hands a skill can be transferred to (:data:`ias_gym.sim.hands.HANDS`)."""
    return list(hands.hand_names())


def hand_workspace(hand: str) -> HandWorkspace:
    """The workspace of a hand, from its ``HandSpec``: the pen centre moves each way along
    each axis and diagonal as far as the expert carries it at the motion's tilt
    (``reach_by_tilt``; synthetic motions stay in a ball of :data:`TRANSLATION_SHARE` of the
    tips' reach) and as fast as it moves it (``skill_speed``); its axis turns up to the
    largest tilt the expert tracks slowly, and as fast as it turns it (``skill_tilt``,
    ``skill_tilt_rate``).

    Raises:
        InputError: an unknown hand (the message lists the known ones).
    """
    spec = hands.get_hand(hand)
    return HandWorkspace(
        reach=TRANSLATION_SHARE * spec.reach,
        tilt=spec.skill_tilt,
        axes=spec.reach_by_tilt,
        tilt_rate=spec.skill_tilt_rate,
        speed=spec.skill_speed,
    )


def workspace_scales(
    ws: HandWorkspace,
    displacement: FloatArray,
    largest_turn: float,
    largest_rate: float = 0.0,
    fastest: float = 0.0,
) -> tuple[float, float]:
    """The translation and rotation scales of a motion (module docstring) that moves the
    pen's centre by ``displacement`` ``(T, 3)`` [m] at up to ``fastest`` [m/s] and turns its
    axis by up to ``largest_turn`` [rad] at up to ``largest_rate`` [rad/s].

    The rotation keeps the turn within the hand's tilt and its rate within the tilt rate;
    the translation keeps the motion within the reach at the scaled tilt and its speed
    within the hand's, and is never above the rotation's scale (with both scaled by k, a
    turn about a pivot stays one about the same pivot; a larger translation scale would
    move the pivot out). As the reach shrinks with the tilt, a tilt held down to a probed
    one below may let the hand carry more of the translation: of these choices the one that
    keeps most of the motion, the largest product of the two scales (then the largest
    rotation), is taken.
    """

    def within(limit: float, value: float) -> float:
        return min(1.0, limit / value) if value > 0 else 1.0

    scale_rot = min(within(ws.tilt, largest_turn), within(ws.tilt_rate, largest_rate))
    speed_scale = within(ws.speed, fastest)
    candidates = [scale_rot]
    if largest_turn > 0:
        candidates += [
            share * ws.tilt / largest_turn
            for share in ws.tilt_shares
            if share * ws.tilt < scale_rot * largest_turn
        ]
    choices = [
        (min(ws.translation_scale(displacement, rot * largest_turn), rot, speed_scale), rot)
        for rot in candidates
    ]
    return max(choices, key=lambda choice: (choice[0] * choice[1], choice[1]))

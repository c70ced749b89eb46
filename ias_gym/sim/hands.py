"""The robot hands that hold the pen: a registry of their layouts (:data:`HANDS`).

A skill stored as the time behaviour of the grip transform G(t) should run on a hand whose
structure differs from the demonstrator's (the paper's Flow 2). The hands share the pen,
the scene's conventions and the sensor names (``fN_abd``/``mcp``/``pip``, ``fN_tip``,
``fN_tip_collision``, ``fN_touch``, ``fN_pen_contact``, ``fN_pen_force``); a
:class:`HandSpec` names what differs: the scene, the fingers and their sides of the pen,
the nominal contacts, how far the tips reach and the largest tilt the expert handles.

- ``"ias4f"``: the four-finger hand of the paper's skill example (``scene_pen.xml``), the
  default everywhere;
- ``"ias3f"``: a three-finger hand (``scene_pen3f.xml``): two short fingers above the pen at
  -3 and +3 cm pushing down and a long opposed "thumb" below its centre
  (``ias_gym/assets/README.md``, docs/DESIGN.md "The second hand");
- ``"shadow"``: the Shadow Dexterous Hand of Gymnasium-Robotics, loaded from that installed
  package (:mod:`ias_gym.sim.external_hands`, the ``hands`` extra): its first and little
  finger above the pen at -3.5 and +4 cm, its thumb below the centre;
- ``"leap"``: the LEAP hand of MuJoCo Playground, loaded from that installed package
  (:mod:`ias_gym.sim.leap_hand`): its index and middle finger below the pen at +2.25 and
  -2.25 cm, its thumb on top at the centre.

Paper frame (x along the pen, y up, z lateral), SI units.
"""

from __future__ import annotations

from dataclasses import dataclass

from ias_gym.errors import InputError

__all__ = ["DEFAULT_HAND", "HANDS", "HandSpec", "get_hand", "hand_names"]


#: The see-saw amplitudes of ``HandSpec.reach_by_tilt``, as shares of ``skill_tilt`` [-].
REACH_TILT_SHARES = (0.25, 0.5, 0.75, 1.0)
#: The planes of two axes (x 0, y 1, z 2) whose diagonals ``HandSpec.reach_by_tilt`` has.
REACH_PLANES = ((0, 1), (1, 2), (0, 2))
#: The directions of ``HandSpec.reach_by_tilt``: both ways along each axis of the pen's
#: start frame (``+x``, ``-x``, ``+y``, ...), then the four diagonals of each of
#: :data:`REACH_PLANES` (``+x+y``, ``+x-y``, ``-x+y``, ``-x-y``, ``+y+z``, ...).
REACH_DIRECTIONS = tuple(f"{sign}{axis}" for axis in "xyz" for sign in "+-") + tuple(
    f"{sa}{'xyz'[a]}{sb}{'xyz'[b]}" for a, b in REACH_PLANES for sa in "+-" for sb in "+-"
)


def reach_direction(name: str) -> tuple[float, float, float]:
    """The unit vector of a name of :data:`REACH_DIRECTIONS` (``"-y+z"``: (0, -0.71, 0.71))."""
    if name not in REACH_DIRECTIONS:
        raise InputError(f"unknown reach direction {name!r}; known: {', '.join(REACH_DIRECTIONS)}")
    vector = [0.0, 0.0, 0.0]
    for sign, axis in zip(name[::2], name[1::2], strict=True):
        vector["xyz".index(axis)] = 1.0 if sign == "+" else -1.0
    norm = sum(v * v for v in vector) ** 0.5
    return (vector[0] / norm, vector[1] / norm, vector[2] / norm)


def _mm(*rows: tuple[float, ...]) -> tuple[tuple[float, ...], ...]:
    """Rows of lengths in mm as metres (the reach tables, as ``docs/hand_reach.json`` has
    them: one row per tilt share, one value per direction)."""
    return tuple(tuple(v / 1000.0 for v in row) for row in rows)


@dataclass(frozen=True)
class HandSpec:
    """The layout of one robot hand holding the pen (paper frame, SI units).

    Attributes:
        name: the registry key (``"ias4f"``, ``"ias3f"``, ``"shadow"``, ``"leap"``).
        scene: the MJCF scene in ``ias_gym.assets`` (hand + pen + sensors + keyframe), or
            the name of a builder in :data:`ias_gym.sim.external_hands.BUILDERS`.
        fingers: finger name prefixes in the MJCF, in the hand's order.
        joints: joint suffixes of every finger, proximal to distal.
        sides: per finger, the side of the pen it touches: +1 top (pushes down), -1 bottom.
        contact_x: per finger, the nominal contact position along the pen's axis from its
            centre [m] (the ``grasp`` keyframe's).
        reach: how far every tip reaches along the pen from its nominal contact, both ways,
            with the pen at rest [m]: the smallest distance in :attr:`contact_range`.
        contact_range: per finger, the lowest and highest contact position along the pen
            [m] its tip reaches with the pen at rest and the other tips at their nominal
            contacts (inverse kinematics within the joint ranges, no link touching the pen,
            on the pen's cylinder |x| <= 5 cm; scanned in 1 mm steps).
        max_tilt: the largest see-saw amplitude about the paper's z the Theorem-1 expert
            tracks on this hand at PenRotate's frequencies, up to 12 rad/s [rad] (measured,
            docs/DESIGN.md).
        skill_tilt: the largest see-saw amplitude the expert tracks at 0.5 Hz under 70 % of
            the pen's friction [rad]: a transferred skill's largest tilt
            (``train/hand_reach.py``, ``docs/hand_reach.json``).
        skill_tilt_rate: the fastest turn of the pen's axis the expert tracks at 1 and 2 Hz
            under 70 % of the pen's friction [rad/s]: a transferred skill's fastest.
        skill_speed: the fastest the expert moves the pen's centre, swaying it along each
            axis at 1 and 2 Hz under 70 % of the pen's friction [m/s]: a transferred
            skill's fastest.
        reach_by_tilt: how far the expert carries the pen's centre and holds it there [m],
            along each of :data:`REACH_DIRECTIONS` (x along the pen, y up, z lateral, both
            ways, and the diagonals between two axes), while see-sawing it at
            :data:`REACH_TILT_SHARES` of ``skill_tilt``, under 70 % of the pen's friction:
            one value per direction and share (measured by ``train/hand_reach.py``,
            ``docs/hand_reach.json``).
        description: one line for listings.
    """

    name: str
    scene: str
    fingers: tuple[str, ...]
    joints: tuple[str, ...]
    sides: tuple[float, ...]
    contact_x: tuple[float, ...]
    reach: float
    contact_range: tuple[tuple[float, float], ...]
    max_tilt: float
    skill_tilt: float
    skill_tilt_rate: float
    skill_speed: float
    reach_by_tilt: tuple[tuple[float, ...], ...]
    description: str

    def __post_init__(self) -> None:
        k = len(self.fingers)
        if not len(self.sides) == len(self.contact_x) == len(self.contact_range) == k:
            raise ValueError(
                f"hand {self.name!r}: sides, contact_x and contact_range need one entry per finger"
            )
        if len(self.reach_by_tilt) != len(REACH_TILT_SHARES) or any(
            len(row) != len(REACH_DIRECTIONS) for row in self.reach_by_tilt
        ):
            raise ValueError(
                f"hand {self.name!r}: reach_by_tilt needs one value per direction "
                f"{REACH_DIRECTIONS} and tilt share {REACH_TILT_SHARES}"
            )
        if not ({1.0, -1.0} <= set(self.sides) <= {1.0, -1.0}):
            raise ValueError(f"hand {self.name!r}: sides must be +1 or -1, on both sides")

    @property
    def n_fingers(self) -> int:
        """Number of fingers k."""
        return len(self.fingers)

    @property
    def n_dofs(self) -> int:
        """Number of hand joints (and motors)."""
        return len(self.fingers) * len(self.joints)


#: The four-finger hand is the default of every pen task.
DEFAULT_HAND = "ias4f"

#: The registered hands, by name.
HANDS: dict[str, HandSpec] = {
    "ias4f": HandSpec(
        name="ias4f",
        scene="scene_pen.xml",
        fingers=("f1", "f2", "f3", "f4"),
        joints=("abd", "mcp", "pip"),
        sides=(1.0, -1.0, -1.0, 1.0),
        contact_x=(-0.03, -0.02, 0.02, 0.03),
        reach=0.02,
        contact_range=((-0.05, 0.012), (-0.05, 0.022), (-0.022, 0.05), (-0.012, 0.05)),
        # PenRotate's limit since v0 (docs/DESIGN.md, "Envelope of the 4-finger hand").
        max_tilt=0.35,
        skill_tilt=0.375,
        skill_tilt_rate=5.0265,
        skill_speed=0.0754,
        reach_by_tilt=_mm(
            (14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14),
            (14, 14, 14, 14, 12, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14),
            (14, 14, 8, 8, 12, 12, 8, 10, 8, 10, 12, 12, 12, 12, 14, 14, 14, 14),
            (6, 8, 2, 2, 10, 10, 2, 4, 4, 4, 2, 2, 4, 4, 14, 14, 14, 14),
        ),
        description="four fingers, two above and two below the pen (the paper's skill example)",
    ),
    "ias3f": HandSpec(
        name="ias3f",
        scene="scene_pen3f.xml",
        fingers=("f1", "f2", "f3"),
        joints=("abd", "mcp", "pip"),
        sides=(1.0, -1.0, 1.0),
        contact_x=(-0.03, 0.0, 0.03),
        reach=0.02,
        contact_range=((-0.05, 0.014), (-0.049, 0.049), (-0.014, 0.05)),
        # 5 / 5 seeds succeed at A = 0.4 rad for w = 2..12 rad/s, not at 0.45 rad, 12 rad/s.
        max_tilt=0.4,
        skill_tilt=0.4,
        skill_tilt_rate=5.0265,
        skill_speed=0.05027,
        reach_by_tilt=_mm(
            (14, 14, 14, 14, 10, 10, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14),
            (14, 14, 14, 14, 10, 10, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14),
            (14, 14, 14, 12, 10, 10, 12, 14, 12, 14, 12, 12, 14, 14, 14, 14, 12, 14),
            (14, 14, 6, 10, 8, 8, 8, 12, 8, 10, 10, 10, 10, 10, 12, 12, 12, 12),
        ),
        description="three fingers: two short ones above the pen, a long thumb below its centre",
    ),
    "shadow": HandSpec(
        name="shadow",
        scene="shadow",
        fingers=("f1", "f2", "f3"),
        joints=("abd", "mcp", "pip"),
        sides=(1.0, -1.0, 1.0),
        contact_x=(-0.035, 0.0, 0.04),
        reach=0.008,
        contact_range=((-0.047, -0.013), (-0.04, 0.008), (0.029, 0.05)),
        # 8 / 8 seeds at A = 0.15 rad for w = 2, 7, 12 rad/s; at 12 rad/s 0.2 rad loses 1 of
        # 6 (the contacts creep around the pen until the internal-force LP is infeasible).
        max_tilt=0.15,
        skill_tilt=0.3,
        skill_tilt_rate=1.7279,
        skill_speed=0.04398,
        reach_by_tilt=_mm(
            (6, 8, 8, 10, 6, 6, 8, 8, 10, 6, 6, 6, 6, 14, 8, 8, 6, 8),
            (6, 6, 6, 6, 4, 4, 8, 8, 10, 4, 4, 4, 4, 10, 6, 6, 4, 6),
            (6, 4, 2, 4, 4, 2, 4, 6, 6, 4, 4, 2, 4, 4, 6, 2, 4, 2),
            (2, 0, 0, 0, 4, 0, 2, 6, 0, 0, 4, 0, 2, 0, 2, 0, 2, 0),
        ),
        description="the Shadow hand (Gymnasium-Robotics' model): first and little finger "
        "above the pen, the thumb below",
    ),
    "leap": HandSpec(
        name="leap",
        scene="leap",
        fingers=("f1", "f2", "f3"),
        joints=("abd", "mcp", "pip"),
        sides=(-1.0, 1.0, -1.0),
        contact_x=(0.0225, 0.0, -0.0225),
        reach=0.02,
        contact_range=((-0.0025, 0.044), (-0.042, 0.0535), (-0.047, -0.0025)),
        # 3 / 3 development seeds 100-102 at A = 0.075 rad for w = 2, 7, 12 rad/s (RMS tilt
        # error 3.5-3.8 % of A at 12 rad/s)
        max_tilt=0.075,
        skill_tilt=0.4,
        skill_tilt_rate=1.5708,
        skill_speed=0.02513,
        reach_by_tilt=_mm(
            (14, 10, 14, 14, 10, 12, 12, 14, 12, 14, 14, 12, 10, 14, 14, 14, 14, 14),
            (14, 8, 8, 14, 10, 10, 6, 14, 8, 14, 8, 8, 8, 14, 12, 12, 12, 10),
            (8, 6, 4, 14, 10, 10, 4, 14, 6, 12, 6, 6, 10, 14, 10, 6, 10, 8),
            (6, 8, 4, 14, 10, 10, 4, 14, 8, 14, 8, 6, 10, 14, 10, 6, 12, 10),
        ),
        description="the LEAP hand (MuJoCo Playground's model): index and middle finger "
        "below the pen, the thumb on top",
    ),
}


def hand_names() -> list[str]:
    """The registered hands' names, sorted."""
    return sorted(HANDS)


def get_hand(name: str) -> HandSpec:
    """The :class:`HandSpec` registered as ``name``.

    Args:
        name: a key of :data:`HANDS`.

    Returns:
        The hand's spec.

    Raises:
        InputError: no hand of that name; the message lists the known hands.
    """
    try:
        return HANDS[name]
    except (KeyError, TypeError):
        raise InputError(f"unknown hand {name!r}; known hands: {', '.join(hand_names())}") from None

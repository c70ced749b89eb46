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


#: The see-saw amplitudes of ``HandSpec.reach_by_tilt``, as shares of ``max_tilt`` [-].
REACH_TILT_SHARES = (0.25, 0.5, 1.0)


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
            tracks on this hand [rad] (measured, docs/DESIGN.md).
        reach_by_tilt: how far the expert carries the pen's centre out and back along x
            (the pen), y (up) and z (lateral) [m] while see-sawing it at
            :data:`REACH_TILT_SHARES` of ``max_tilt``, one ``(x, y, z)`` per share (measured
            by ``train/hand_reach.py``, ``docs/hand_reach.json``).
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
    reach_by_tilt: tuple[tuple[float, float, float], ...]
    description: str

    def __post_init__(self) -> None:
        k = len(self.fingers)
        if not len(self.sides) == len(self.contact_x) == len(self.contact_range) == k:
            raise ValueError(
                f"hand {self.name!r}: sides, contact_x and contact_range need one entry per finger"
            )
        if len(self.reach_by_tilt) != len(REACH_TILT_SHARES):
            raise ValueError(f"hand {self.name!r}: reach_by_tilt needs one (x, y, z) per share")
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
        reach_by_tilt=((0.014, 0.014, 0.014), (0.014, 0.014, 0.014), (0.014, 0.004, 0.014)),
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
        reach_by_tilt=((0.014, 0.014, 0.014), (0.014, 0.014, 0.014), (0.014, 0.008, 0.014)),
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
        reach_by_tilt=((0.008, 0.012, 0.006), (0.008, 0.012, 0.006), (0.006, 0.012, 0.006)),
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
        reach_by_tilt=((0.014, 0.014, 0.014), (0.014, 0.014, 0.014), (0.014, 0.014, 0.014)),
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

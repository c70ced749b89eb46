"""The human hand as the glove sees it: joint and sensor names, ranges, a person's parameters.

Paper section 2.3: the glove has 10 degrees of freedom, "3 for the wrist, 3 for the index
finger, 2 for the thumb and 2 for the rest of the fingers". This module fixes, in one place,

- the 10 joint angles Θ of the kinematic hand model (:data:`JOINT_NAMES`, ranges in
  :data:`JOINT_RANGES` [rad]; flexion positive);
- the 10 sensor readings Ψ of the glove (:data:`SENSOR_NAMES`, the order in which the
  hardware sends "the 10 readings"), all in [rad];
- :class:`PersonParams`: the person-dependent part of the sensor model of eq. (1), sampled
  reproducibly from a person id and a seed (hand size, segment lengths, how the glove sits);
- the planar forward kinematics of index finger and thumb (the side view of Fig. 7): the
  index finger flexes in its sagittal plane; the thumb is drawn in the same plane (a
  stylised projection, our choice): its metacarpal leaves the CMC joint below and behind the
  index MCP and swings palmar with the CMC rotation/abduction angle, its flexion bends MCP
  and IP towards the index finger. Pinching = the two fingertips meet in this plane.

Frame of the kinematics [m]: origin at the index MCP joint, x distal along the index
metacarpal, y palmar (so flexion angles turn counter-clockwise). Points are complex numbers
``x + 1j * y`` internally, ``(..., 2)`` arrays at the interface.

Joint coupling of natural poses (our model, documented here): the index DIP follows the PIP,
``θ3 ≈ κ θ2`` with a person's κ ≈ 2/3 (:attr:`PersonParams.dip_coupling`), but not in a pinch,
where the contact sets the DIP (pad pinch: DIP nearly straight; tip pinch: flexed). The thumb's
flexion θ_tf is shared by its MCP and IP joints (:data:`THUMB_FLEXION_SHARES`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ias_gym.errors import InputError
from ias_gym.glove.ids import check_id
from ias_gym.glove.population import PersonStream, draw_hand_scale

#: The joint angles Θ of the hand model, in this order (paper 2.3) [rad].
JOINT_NAMES: tuple[str, ...] = (
    "wrist_flexion",  # + flexion, - extension
    "wrist_deviation",  # + ulnar, - radial
    "wrist_pronation",  # + pronation, - supination
    "index_mcp",  # θ1 of Fig. 4
    "index_pip",  # θ2
    "index_dip",  # θ3
    "thumb_cmc",  # CMC rotation/abduction (palmar abduction towards opposition)
    "thumb_flexion",  # MCP + IP flexion, shared (THUMB_FLEXION_SHARES)
    "fingers_mcp",  # middle, ring, little finger MCP, moving together
    "fingers_pip",  # their PIP (DIP follows, not measured)
)
N_JOINTS = len(JOINT_NAMES)

#: (low, high) of each joint [rad]: physiological active ranges, rounded.
JOINT_RANGES: dict[str, tuple[float, float]] = {
    "wrist_flexion": (-1.0, 1.0),
    "wrist_deviation": (-0.35, 0.45),
    "wrist_pronation": (-1.2, 1.2),
    "index_mcp": (0.0, 1.5),
    "index_pip": (0.0, 1.7),
    "index_dip": (0.0, 1.2),
    "thumb_cmc": (0.0, 1.2),
    "thumb_flexion": (0.0, 1.3),
    "fingers_mcp": (0.0, 1.5),
    "fingers_pip": (0.0, 1.7),
}
JOINT_LOW = np.array([JOINT_RANGES[n][0] for n in JOINT_NAMES])
JOINT_HIGH = np.array([JOINT_RANGES[n][1] for n in JOINT_NAMES])

#: The glove's sensor readings Ψ, in the order the hardware sends them [rad].
SENSOR_NAMES: tuple[str, ...] = (
    "wrist_flexion",  # potentiometers on the wrist gimbal (3)
    "wrist_deviation",
    "wrist_pronation",
    "index_psi1",  # ψ1: the index linkage's base angle (Fig. 4)
    "index_psi2",  # ψ2: the linkage's middle angle (Fig. 4)
    "thumb_flexion",  # bend sensor over thumb MCP + IP
    "thumb_rotation",  # potentiometer of the thumb's CMC linkage
    "thumb_web",  # thumb-index web (abduction) linkage: couples thumb and index
    "fingers_mcp",  # bend sensors over the other fingers (2)
    "fingers_pip",
)
N_SENSORS = len(SENSOR_NAMES)

#: Indices into Θ of the finger groups.
WRIST_JOINTS = (0, 1, 2)
INDEX_JOINTS = (3, 4, 5)
THUMB_JOINTS = (6, 7)
FINGERS_JOINTS = (8, 9)

#: Share of the thumb flexion θ_tf taken by the thumb's MCP and IP joints (sum 1).
THUMB_FLEXION_SHARES = (0.55, 0.45)
#: Direction of the thumb metacarpal at θ_cmc = 0 [rad], counter-clockwise from +x (x distal,
#: y palmar): the adducted thumb lies along the index metacarpal, slightly dorsal.
THUMB_REST_ANGLE = -0.35

#: Nominal adult segment lengths [m] (scale 1): index proximal, middle, distal phalanx.
NOMINAL_INDEX_LENGTHS = (0.045, 0.026, 0.019)
#: Thumb metacarpal, proximal and distal phalanx [m].
NOMINAL_THUMB_LENGTHS = (0.046, 0.032, 0.026)
#: Thumb CMC joint relative to the index MCP [m] (proximal, palmar).
NOMINAL_THUMB_BASE = (-0.052, 0.030)
#: Pivot of the glove's index linkage relative to the MCP on the nominal hand [m].
NOMINAL_LINKAGE_BASE = (-0.018, -0.024)
#: Dorsal height of the glove's rings above the bone line, scale 1 [m].
NOMINAL_FINGER_THICKNESS = 0.009
#: Fingertip distance below which the pads touch, scale 1 [m].
NOMINAL_PAD_CONTACT = 0.006


def joint_index(name: str) -> int:
    """Index of joint ``name`` in Θ.

    Raises:
        KeyError: listing the joint names that exist.
    """
    try:
        return JOINT_NAMES.index(name)
    except ValueError:
        raise KeyError(f"unknown joint {name!r}; joints: {list(JOINT_NAMES)}") from None


def sensor_index(name: str) -> int:
    """Index of sensor ``name`` in Ψ.

    Raises:
        KeyError: listing the sensor names that exist.
    """
    try:
        return SENSOR_NAMES.index(name)
    except ValueError:
        raise KeyError(f"unknown sensor {name!r}; sensors: {list(SENSOR_NAMES)}") from None


@dataclass(frozen=True)
class PersonParams:
    """The person-dependent part of the sensor model Ψ = g_person(Θ) (eq. (1) inverted).

    Sample one with :meth:`sample`; :meth:`nominal` is the average person with a perfectly
    mounted glove. Lengths in [m], angles in [rad], forces in [N]. The distributions named
    below (``hand_length_men`` ...) are :data:`ias_gym.glove.population.PARAMETERS`.

    Attributes:
        person_id: who this is.
        seed: the seed the parameters were sampled with (with ``person_id``).
        hand_scale: hand length over the nominal adult's (-): ``hand_length_men`` or
            ``hand_length_women``.
        index_lengths: index proximal, middle, distal phalanx [m] = nominal x scale x a
            per-segment ``segment_ratio``.
        thumb_lengths: thumb metacarpal, proximal, distal phalanx [m], likewise.
        thumb_base: thumb CMC joint (x, y) relative to the index MCP [m], scaled, plus
            ``thumb_base_offset``.
        dip_coupling: κ of the natural DIP-PIP coupling θ3 ≈ κ θ2 (``dip_coupling``).
        linkage_base: the pivot of the glove's index linkage (ψ1's potentiometer) relative to
            the person's MCP [m]: fixed on the glove at (-18, -24) mm (behind the MCP, on the
            back of the hand), so it sits differently on every hand (``linkage_offset``).
        linkage_attach: where the linkage's ring and thimble sit: fraction along the
            proximal phalanx, fraction along the distal phalanx (-) (``ring_*``).
        finger_thickness: dorsal height of the rings above the bone line [m], scaled.
        gains: per-sensor gain (-) (``sensor_gain``).
        offsets: per-sensor zero offset [rad] (``sensor_offset``).
        wrist_mount: rotation of the wrist gimbal's flexion/deviation axes relative to the
            anatomical axes [rad] (``wrist_mount``).
        thumb_crosstalk: thumb_cmc seen by the thumb flexion bend sensor (-) (``crosstalk``).
        fingers_crosstalk: the fingers' MCP seen by their PIP bend sensor (-), likewise.
        pad_contact: fingertip distance [m] below which thumb and index pads touch,
            6 mm x scale.
        pad_stiffness: pinch force per metre of pad compression [N/m] (``pad_stiffness``).
        push_linkage: contact force turning the index's thimble, added to ψ2 [rad/N],
            (``push_linkage``).
        push_web: contact force opening the thumb-index web sensor [rad/N] (``push_web``).
        push_thumb: contact force extending the thumb's bend sensor [rad/N] (enters
            negatively) (``push_thumb``).
        range_of_motion: factor on the active ranges of the wrist, index and thumb joints (-)
            (``range_of_motion``): :attr:`joint_limits`.
    """

    person_id: str
    seed: int
    hand_scale: float
    index_lengths: tuple[float, float, float]
    thumb_lengths: tuple[float, float, float]
    thumb_base: tuple[float, float]
    dip_coupling: float
    linkage_base: tuple[float, float]
    linkage_attach: tuple[float, float]
    finger_thickness: float
    gains: tuple[float, ...]
    offsets: tuple[float, ...]
    wrist_mount: float
    thumb_crosstalk: float
    fingers_crosstalk: float
    pad_contact: float
    pad_stiffness: float
    push_linkage: float
    push_web: float
    push_thumb: float
    range_of_motion: float = 1.0

    def __post_init__(self) -> None:
        # The id names this person's profile files: one rule for every id (glove.ids).
        check_id(self.person_id, "person_id")
        for name in ("gains", "offsets"):
            value = getattr(self, name)
            if len(value) != N_SENSORS:
                raise ValueError(f"{name} must have {N_SENSORS} entries, got {len(value)}")
        numbers = (self.hand_scale, self.range_of_motion, *self.index_lengths, *self.thumb_lengths)
        if not all(math.isfinite(v) and v > 0 for v in numbers):
            raise InputError(
                f"{self.person_id}: hand_scale, range_of_motion and segment lengths must be "
                f"positive and finite, got hand_scale={self.hand_scale}, range_of_motion="
                f"{self.range_of_motion}, index={self.index_lengths}, thumb={self.thumb_lengths}"
            )

    @classmethod
    def nominal(cls, person_id: str = "nominal") -> PersonParams:
        """The average person (scale 1) with a perfectly mounted glove."""
        return cls(
            person_id=person_id,
            seed=0,
            hand_scale=1.0,
            index_lengths=NOMINAL_INDEX_LENGTHS,
            thumb_lengths=NOMINAL_THUMB_LENGTHS,
            thumb_base=NOMINAL_THUMB_BASE,
            dip_coupling=2.0 / 3.0,
            linkage_base=NOMINAL_LINKAGE_BASE,
            linkage_attach=(0.6, 0.5),
            finger_thickness=NOMINAL_FINGER_THICKNESS,
            gains=(1.0,) * N_SENSORS,
            offsets=(0.0,) * N_SENSORS,
            wrist_mount=0.0,
            thumb_crosstalk=0.1,
            fingers_crosstalk=0.1,
            pad_contact=NOMINAL_PAD_CONTACT,
            pad_stiffness=1000.0,
            push_linkage=0.03,
            push_web=0.04,
            push_thumb=0.015,
        )

    @classmethod
    def sample(cls, person_id: str, seed: int = 0) -> PersonParams:
        """Draw a person's hand from the population, reproducibly from ``(person_id, seed)``.

        Every number comes from its documented distribution
        (:data:`ias_gym.glove.population.PARAMETERS`, ``docs/population.md``).

        Raises:
            InputError: ``person_id`` is not a valid id (:func:`~ias_gym.glove.ids.check_id`).
        """
        stream = PersonStream(person_id, "hand", seed)
        s = draw_hand_scale(stream)

        def lengths(nominal: tuple[float, float, float]) -> tuple[float, float, float]:
            r = stream.draws("segment_ratio", 3)
            return (nominal[0] * s * r[0], nominal[1] * s * r[1], nominal[2] * s * r[2])

        index_lengths = lengths(NOMINAL_INDEX_LENGTHS)
        thumb_lengths = lengths(NOMINAL_THUMB_LENGTHS)
        base = np.array(NOMINAL_THUMB_BASE) * s + stream.draws("thumb_base_offset", 2)
        linkage = np.array(NOMINAL_LINKAGE_BASE) + stream.draws("linkage_offset", 2)
        return cls(
            person_id=person_id,
            seed=seed,
            hand_scale=s,
            index_lengths=index_lengths,
            thumb_lengths=thumb_lengths,
            thumb_base=(float(base[0]), float(base[1])),
            dip_coupling=stream.draw("dip_coupling"),
            linkage_base=(float(linkage[0]), float(linkage[1])),
            linkage_attach=(stream.draw("ring_proximal"), stream.draw("ring_distal")),
            finger_thickness=NOMINAL_FINGER_THICKNESS * s,
            gains=stream.draws("sensor_gain", N_SENSORS),
            offsets=stream.draws("sensor_offset", N_SENSORS),
            wrist_mount=stream.draw("wrist_mount"),
            thumb_crosstalk=stream.draw("crosstalk"),
            fingers_crosstalk=stream.draw("crosstalk"),
            pad_contact=NOMINAL_PAD_CONTACT * s,
            pad_stiffness=stream.draw("pad_stiffness"),
            push_linkage=stream.draw("push_linkage"),
            push_web=stream.draw("push_web"),
            push_thumb=stream.draw("push_thumb"),
            range_of_motion=stream.draw("range_of_motion"),
        )

    @property
    def joint_limits(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(low, high)`` ``(10,)`` this person's active joint ranges [rad]: the population's
        (:data:`JOINT_RANGES`) times :attr:`range_of_motion` for the wrist, index and thumb;
        the other fingers (curled out of the way in every task) keep the population's."""
        scale = np.ones(N_JOINTS)
        scale[list(WRIST_JOINTS + INDEX_JOINTS + THUMB_JOINTS)] = self.range_of_motion
        return JOINT_LOW * scale, JOINT_HIGH * scale

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able dict (tuples as lists)."""
        out: dict[str, Any] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            out[f.name] = list(value) if isinstance(value, tuple) else value
        return out


def _e(angle: NDArray[np.float64]) -> NDArray[np.complex128]:
    return np.exp(1j * angle)


def index_points(theta: ArrayLike, lengths: tuple[float, float, float]) -> NDArray[np.complex128]:
    """Index MCP, PIP, DIP and fingertip as complex ``x + iy`` [m], shape ``(..., 4)``.

    Args:
        theta: ``(..., 3)`` index angles θ1 (MCP), θ2 (PIP), θ3 (DIP) [rad].
        lengths: proximal, middle, distal phalanx [m].
    """
    th = np.asarray(theta, dtype=np.float64)
    phi = np.cumsum(th, axis=-1)
    segments = np.asarray(lengths) * _e(phi)
    zero = np.zeros((*th.shape[:-1], 1), dtype=np.complex128)
    return np.concatenate([zero, np.cumsum(segments, axis=-1)], axis=-1)


def thumb_directions(theta: ArrayLike) -> NDArray[np.float64]:
    """Directions of the thumb's metacarpal, proximal and distal phalanx [rad], ``(..., 3)``.

    Args:
        theta: ``(..., 2)`` thumb CMC rotation/abduction and flexion [rad].
    """
    th = np.asarray(theta, dtype=np.float64)
    a1 = THUMB_REST_ANGLE + th[..., 0]  # abduction swings the metacarpal palmar
    # Thumb flexion bends MCP and IP back towards the index finger (clockwise here).
    a2 = a1 - THUMB_FLEXION_SHARES[0] * th[..., 1]
    a3 = a2 - THUMB_FLEXION_SHARES[1] * th[..., 1]
    return np.stack([a1, a2, a3], axis=-1)


def thumb_points(
    theta: ArrayLike, lengths: tuple[float, float, float], base: tuple[float, float]
) -> NDArray[np.complex128]:
    """Thumb CMC, MCP, IP and tip as complex ``x + iy`` [m], shape ``(..., 4)``.

    Args:
        theta: ``(..., 2)`` thumb CMC rotation/abduction and flexion [rad].
        lengths: metacarpal, proximal, distal phalanx [m].
        base: CMC position relative to the index MCP [m].
    """
    segments = np.asarray(lengths) * _e(thumb_directions(theta))
    origin = np.full((*segments.shape[:-1], 1), complex(base[0], base[1]))
    return np.concatenate([origin, origin + np.cumsum(segments, axis=-1)], axis=-1)


def hand_points(
    theta: ArrayLike, person: PersonParams
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Index and thumb stick figures of full poses Θ: two ``(..., 4, 2)`` arrays [m]."""
    th = np.asarray(theta, dtype=np.float64)
    idx = index_points(th[..., list(INDEX_JOINTS)], person.index_lengths)
    thb = thumb_points(th[..., list(THUMB_JOINTS)], person.thumb_lengths, person.thumb_base)
    return (np.stack([idx.real, idx.imag], -1), np.stack([thb.real, thb.imag], -1))


def tip_vector(theta: ArrayLike, person: PersonParams) -> NDArray[np.float64]:
    """Thumb tip minus index tip (x, y) [m] of poses Θ, shape ``(..., 2)``."""
    th = np.asarray(theta, dtype=np.float64)
    idx = index_points(th[..., list(INDEX_JOINTS)], person.index_lengths)[..., -1]
    thb = thumb_points(th[..., list(THUMB_JOINTS)], person.thumb_lengths, person.thumb_base)
    d = thb[..., -1] - idx
    return np.stack([d.real, d.imag], axis=-1)


def fingertip_gap(theta: ArrayLike, person: PersonParams) -> NDArray[np.float64]:
    """Distance between the thumb tip and the index tip [m] of poses Θ, shape ``(...)``."""
    return np.asarray(np.linalg.norm(tip_vector(theta, person), axis=-1))

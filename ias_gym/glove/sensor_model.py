"""The glove's sensor model Ψ = g_person(Θ) + noise, and calibration sessions.

The paper's eq. (1), Θ = f(Ψ), is the calibration mapping; this module simulates its inverse:
what the glove reads when a person's hand is in pose Θ. All angles in [rad], lengths in
[m], forces in [N]; Θ and Ψ in the orders of :data:`~ias_gym.glove.hand.JOINT_NAMES` and
:data:`~ias_gym.glove.hand.SENSOR_NAMES`. The person-dependent parameters are those of
:class:`~ias_gym.glove.hand.PersonParams`; ``g`` = gain, ``o`` = offset of each sensor.

Wrist (3 potentiometers on a gimbal whose axes sit rotated by the mounting angle m)::

    ψ_wf = g (cos m θ_f + sin m θ_d) + o,   ψ_wd = g (-sin m θ_f + cos m θ_d) + o,
    ψ_wp = g θ_p + o

Index finger, the linkage of Fig. 4 as a planar mechanism over the finger (side view, x
distal, y palmar, origin at the MCP; :func:`linkage_angles`; our model, the scan of Fig. 4
is not legible): a pivot B on the glove's back plate (``linkage_base``, fixed on the glove,
so it sits differently on every hand), a ring A on the proximal phalanx and a thimble D on
the distal phalanx (at ``linkage_attach`` along the bone, ``finger_thickness`` dorsal of
it; complex points ``x + iy``). ψ1 is the angle of the link B→A (potentiometer at B), ψ2 the
angle between the link A→D and the thimble, i.e. the distal phalanx, direction
φ3 = θ1 + θ2 + θ3 (potentiometer at D)::

    ψ1 = g ∠(A - B) + o,   ψ2 = g ∠(e^{iφ3} / (D - A)) + o + push_linkage F

Two readings for three joints: in natural poses the DIP follows the PIP (θ3 ≈ κ θ2), so
(ψ1, ψ2) determine (θ1, θ2, θ3) up to the spread of that coupling; in a pinch it does not,
and the index is recoverable only together with the thumb readings, which say where the
fingertip is pinned. (A linkage with both rings on the middle and distal phalanges leaves
the pinch DIP nearly unobservable: with the tip pinned the rings hardly move, Cramér-Rao
bound about 9 deg at this noise; with ring A on the proximal phalanx and ψ2 against the
thimble it is about 1 deg.)

Thumb (bend sensor over MCP + IP, potentiometer on the CMC linkage, and the thumb-index web
sensor: a link from the thumb's MCP to the index's proximal phalanx at 30 % of its length,
its angle measured against the thumb metacarpal, :func:`web_angle`)::

    ψ_tf = g (θ_tf + thumb_crosstalk θ_cmc) + o - push_thumb F,   ψ_tr = g θ_cmc + o,
    ψ_web = g web_angle(θ_cmc, θ1) + o + push_web F

Other fingers (bend sensors; the PIP strip also bends with the MCP)::

    ψ_fm = g θ_m + o,   ψ_fp = g (θ_p + fingers_crosstalk θ_m) + o

Pinch cross-coupling (paper 4.1, Fig. 7): when the thumb and index pads touch, i.e. the
fingertip distance (planar kinematics of :mod:`ias_gym.glove.hand`) falls below
``pad_contact`` (6 mm x hand scale), the pinch force ``F = pad_stiffness (pad_contact -
gap)`` (about 1 N/mm; the session's pinch poses press with 1-4 N) turns the index's
thimble (ψ2), opens the web sensor (ψ_web) and extends the thumb's bend sensor (ψ_tf), by
``push_*`` [rad/N] x F. F is zero otherwise. Together with the DIP decoupling this is what
makes a linear calibration fail in pinch poses while a small ANN that also sees the thumb
readings recovers the joints.

Noise: independent Gaussian per reading, :data:`NOISE_STD` = 0.4 deg.

Calibration sessions (paper 2.4): :func:`record_session` has a person make free poses (every
joint uniform in its range, DIP coupled to PIP, fingertips at least :data:`FREE_MIN_GAP`
apart) and pinch poses (:func:`sample_pinch_poses`: thumb, DIP and pinch force sampled, the
index put on the thumb by inverse kinematics), and returns Θ, Ψ and which were pinches.

Person parameters and their distributions (sampled by :meth:`PersonParams.sample`): hand
scale U(0.85, 1.15); phalanx lengths = nominal (index 45/26/19 mm, thumb 46/32/26 mm) x
scale x U(0.93, 1.07) each; gains U(0.95, 1.05); offsets N(0, 0.05) rad; wrist mounting
N(0, 0.06) rad; linkage pivot +-3 mm; ring positions U(0.5, 0.7) / U(0.4, 0.6) of the
phalanx; DIP coupling κ U(0.6, 0.75); cross-talk U(0.05, 0.15); pad stiffness U(0.8, 1.2)
N/mm; pushes [rad/N]: linkage U(0.025, 0.04), web U(0.03, 0.05), thumb U(0.01, 0.02).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ias_gym.glove.hand import (
    INDEX_JOINTS,
    JOINT_HIGH,
    JOINT_LOW,
    N_JOINTS,
    THUMB_FLEXION_SHARES,
    THUMB_REST_ANGLE,
    PersonParams,
    fingertip_gap,
    index_points,
    joint_index,
    thumb_directions,
    thumb_points,
)

#: Standard deviation of the sensor noise [rad] (0.4 deg).
NOISE_STD = float(np.deg2rad(0.4))
#: Spread of the natural DIP-PIP coupling θ3 = κ θ2 + N(0, DIP_SPREAD) [rad].
DIP_SPREAD = 0.02
#: Free poses keep the fingertips at least this far apart [m] (closer would be a pinch).
FREE_MIN_GAP = 0.015
#: Range of the pinch DIP angle [rad] (pad pinch ... tip pinch), independent of the PIP.
PINCH_DIP_RANGE = (0.0, 0.6)
#: Ranges of the thumb in pinch poses [rad]: CMC rotation/abduction, flexion.
PINCH_THUMB_RANGES = ((0.3, 1.2), (0.1, 1.3))
#: Pinch force range sampled in pinch poses [N] (sets how far the pads are pressed).
PINCH_FORCE_RANGE = (1.0, 4.0)

#: Rounds of rejection sampling before giving up (each draws several times what is needed).
_MAX_ROUNDS = 50

_WF, _WD, _WP = joint_index("wrist_flexion"), joint_index("wrist_deviation"), 2
_I1, _I2, _I3 = INDEX_JOINTS
_TC, _TF = joint_index("thumb_cmc"), joint_index("thumb_flexion")
_FM, _FP = joint_index("fingers_mcp"), joint_index("fingers_pip")


def linkage_angles(
    theta_index: ArrayLike, person: PersonParams
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Geometric angles (ψ1, ψ2) of the index linkage (Fig. 4) before gain/offset [rad].

    Args:
        theta_index: ``(..., 3)`` index θ1, θ2, θ3 [rad].
        person: segment lengths, ring positions and where the glove's pivot sits.
    """
    th = np.asarray(theta_index, dtype=np.float64)
    p = index_points(th, person.index_lengths)
    phi = np.cumsum(th, axis=-1)
    l1, l3 = person.index_lengths[0], person.index_lengths[2]
    a_frac, d_frac = person.linkage_attach
    dorsal = -1j * person.finger_thickness
    ring_a = p[..., 0] + (a_frac * l1 + dorsal) * np.exp(1j * phi[..., 0])
    ring_d = p[..., 2] + (d_frac * l3 + 0.8 * dorsal) * np.exp(1j * phi[..., 2])
    base = complex(*person.linkage_base)
    ba = ring_a - base
    psi1 = np.angle(ba)
    psi2 = np.angle(np.exp(1j * phi[..., 2]) / (ring_d - ring_a))
    return psi1, psi2


def web_angle(theta: ArrayLike, person: PersonParams) -> NDArray[np.float64]:
    """Opening of the thumb-index web linkage [rad] of full poses Θ ``(..., 10)``."""
    th = np.asarray(theta, dtype=np.float64)
    thumb = thumb_points(th[..., [_TC, _TF]], person.thumb_lengths, person.thumb_base)
    a1 = thumb_directions(th[..., [_TC, _TF]])[..., 0]
    q = 0.3 * person.index_lengths[0] * np.exp(1j * th[..., _I1])
    return np.asarray(a1 - np.angle(q - thumb[..., 1]))


def pinch_force(theta: ArrayLike, person: PersonParams) -> NDArray[np.float64]:
    """Contact force between thumb and index pads [N] of poses Θ (0 when apart)."""
    gap = fingertip_gap(theta, person)
    return np.asarray(person.pad_stiffness * np.maximum(person.pad_contact - gap, 0.0))


def sensor_readings(
    theta: ArrayLike, person: PersonParams, rng: np.random.Generator | None = None
) -> NDArray[np.float64]:
    """Ψ = g_person(Θ) (+ noise when ``rng`` is given) [rad], shape of ``theta``.

    Args:
        theta: ``(..., 10)`` joint angles Θ [rad].
        person: the person wearing the glove.
        rng: noise source; ``None`` gives the noise-free readings.
    """
    th = np.asarray(theta, dtype=np.float64)
    if th.shape[-1:] != (N_JOINTS,):
        raise ValueError(f"theta must have shape (..., {N_JOINTS}), got {th.shape}")
    if th.ndim == 1:
        # One reading per control step (the simulated glove): the same formulas on Python
        # floats, as the ~60 numpy calls below cost ~0.25 ms on arrays of one pose.
        psi = np.array(_one_reading(th.tolist(), person))
        if rng is not None:
            psi += rng.normal(0.0, NOISE_STD, size=psi.shape)
        return psi
    m = person.wrist_mount
    force = pinch_force(th, person)
    psi1, psi2 = linkage_angles(th[..., list(INDEX_JOINTS)], person)
    raw = np.stack(
        [
            np.cos(m) * th[..., _WF] + np.sin(m) * th[..., _WD],
            -np.sin(m) * th[..., _WF] + np.cos(m) * th[..., _WD],
            th[..., _WP],
            psi1,
            psi2,
            th[..., _TF] + person.thumb_crosstalk * th[..., _TC],
            th[..., _TC],
            web_angle(th, person),
            th[..., _FM],
            th[..., _FP] + person.fingers_crosstalk * th[..., _FM],
        ],
        axis=-1,
    )
    psi = np.asarray(person.gains) * raw + np.asarray(person.offsets)
    psi[..., 4] += person.push_linkage * force
    psi[..., 5] -= person.push_thumb * force
    psi[..., 7] += person.push_web * force
    if rng is not None:
        psi += rng.normal(0.0, NOISE_STD, size=psi.shape)
    return psi


def _one_reading(th: list[float], person: PersonParams) -> list[float]:
    """Noise-free Ψ [rad] of one pose Θ ``(10,)`` [rad]: :func:`sensor_readings`'s formulas
    (with :func:`pinch_force`, :func:`linkage_angles`, :func:`web_angle` and the planar
    kinematics of :mod:`ias_gym.glove.hand`) on Python floats, the operations in the same
    order, so the result agrees with the array path to rounding."""
    # Index finger: MCP at 0, PIP, DIP, tip (hand.index_points).
    l1, l2, l3 = person.index_lengths
    phi1 = th[_I1]
    phi2 = phi1 + th[_I2]
    phi3 = phi2 + th[_I3]
    e1 = complex(math.cos(phi1), math.sin(phi1))
    e3 = complex(math.cos(phi3), math.sin(phi3))
    pip = l1 * e1
    dip = pip + l2 * complex(math.cos(phi2), math.sin(phi2))
    index_tip = dip + l3 * e3
    # Thumb: CMC at the base, MCP, IP, tip (hand.thumb_directions, hand.thumb_points).
    tc, tf = th[_TC], th[_TF]
    a1 = THUMB_REST_ANGLE + tc
    a2 = a1 - THUMB_FLEXION_SHARES[0] * tf
    a3 = a2 - THUMB_FLEXION_SHARES[1] * tf
    m1, m2, m3 = person.thumb_lengths
    s1 = m1 * complex(math.cos(a1), math.sin(a1))
    s12 = s1 + m2 * complex(math.cos(a2), math.sin(a2))
    s123 = s12 + m3 * complex(math.cos(a3), math.sin(a3))
    origin = complex(*person.thumb_base)
    thumb_mcp = origin + s1
    thumb_tip = origin + s123
    # pinch_force (hand.fingertip_gap: the norm as numpy takes it, not math.hypot).
    d = thumb_tip - index_tip
    gap = math.sqrt(d.real * d.real + d.imag * d.imag)
    force = person.pad_stiffness * max(person.pad_contact - gap, 0.0)
    # linkage_angles.
    a_frac, d_frac = person.linkage_attach
    dorsal = -1j * person.finger_thickness
    ring_a = (a_frac * l1 + dorsal) * e1  # the MCP is the origin
    ring_d = dip + (d_frac * l3 + 0.8 * dorsal) * e3
    ba = ring_a - complex(*person.linkage_base)
    psi1 = math.atan2(ba.imag, ba.real)
    q2 = e3 / (ring_d - ring_a)
    psi2 = math.atan2(q2.imag, q2.real)
    # web_angle.
    qw = 0.3 * l1 * complex(math.cos(th[_I1]), math.sin(th[_I1])) - thumb_mcp
    web = a1 - math.atan2(qw.imag, qw.real)
    cm, sm = math.cos(person.wrist_mount), math.sin(person.wrist_mount)
    wf, wd = th[_WF], th[_WD]
    raw = (
        cm * wf + sm * wd,
        -sm * wf + cm * wd,
        th[_WP],
        psi1,
        psi2,
        tf + person.thumb_crosstalk * tc,
        tc,
        web,
        th[_FM],
        th[_FP] + person.fingers_crosstalk * th[_FM],
    )
    psi = [g * r + o for g, r, o in zip(person.gains, raw, person.offsets, strict=True)]
    psi[4] += person.push_linkage * force
    psi[5] -= person.push_thumb * force
    psi[7] += person.push_web * force
    return psi


def sample_free_poses(
    n: int, person: PersonParams, rng: np.random.Generator
) -> NDArray[np.float64]:
    """``(n, 10)`` free poses: joints uniform in range, DIP ≈ κ PIP, fingertips apart [rad]."""
    out = np.empty((0, N_JOINTS))
    for _ in range(_MAX_ROUNDS):
        th = rng.uniform(JOINT_LOW, JOINT_HIGH, size=(2 * n, N_JOINTS))
        dip = person.dip_coupling * th[:, _I2] + rng.normal(0.0, DIP_SPREAD, size=2 * n)
        th[:, _I3] = np.clip(dip, JOINT_LOW[_I3], JOINT_HIGH[_I3])
        out = np.concatenate([out, th[fingertip_gap(th, person) >= FREE_MIN_GAP]])
        if len(out) >= n:
            return out[:n]
    raise RuntimeError(f"could not sample {n} free poses for this hand ({len(out)} found)")


def sample_pinch_poses(
    n: int, person: PersonParams, rng: np.random.Generator
) -> NDArray[np.float64]:
    """``(n, 10)`` pinch poses: thumb and index pads pressed together [rad].

    The thumb and the DIP are sampled (:data:`PINCH_THUMB_RANGES`, :data:`PINCH_DIP_RANGE`),
    a pinch force in :data:`PINCH_FORCE_RANGE` sets the pad compression, and θ1, θ2 put the
    index pad on the thumb pad (:func:`index_pinch_angles`); poses outside the joint ranges
    are rejected. Wrist and other fingers are uniform in their ranges.
    """
    lo, hi = JOINT_LOW, JOINT_HIGH
    out = np.empty((0, N_JOINTS))
    for _ in range(_MAX_ROUNDS):
        m = 4 * n
        th = rng.uniform(lo, hi, size=(m, N_JOINTS))
        th[:, _TC] = rng.uniform(*PINCH_THUMB_RANGES[0], size=m)
        th[:, _TF] = rng.uniform(*PINCH_THUMB_RANGES[1], size=m)
        th[:, _I3] = rng.uniform(*PINCH_DIP_RANGE, size=m)
        force = rng.uniform(*PINCH_FORCE_RANGE, size=m)
        th[:, [_I1, _I2]] = index_pinch_angles(th[:, [_TC, _TF]], th[:, _I3], force, person)
        ok = np.all((th >= lo) & (th <= hi), axis=1)  # NaN (unreachable) fails too
        out = np.concatenate([out, th[ok]])
        if len(out) >= n:
            return out[:n]
    raise RuntimeError(f"could not sample {n} pinch poses for this hand ({len(out)} found)")


def index_pinch_angles(
    thumb: ArrayLike, dip: ArrayLike, force: ArrayLike, person: PersonParams
) -> NDArray[np.float64]:
    """Index MCP and PIP [rad] that press the index pad on the thumb pad, ``(..., 2)``.

    The index tip is put ``pad_contact - force / pad_stiffness`` [m] from the thumb tip
    along the thumb pad's normal (the pad faces the side the thumb flexes to); with the DIP
    given, the middle and distal phalanges are one rigid link ``r e^{iδ}`` and θ1, θ2 are
    the two-link inverse kinematics with the PIP flexed. NaN where the tip is out of reach.

    Args:
        thumb: ``(..., 2)`` thumb CMC rotation/abduction and flexion [rad].
        dip: ``(...)`` index DIP angle θ3 [rad].
        force: ``(...)`` pinch force [N].
        person: segment lengths and pad parameters.
    """
    th = np.asarray(thumb, dtype=np.float64)
    l1, l2, l3 = person.index_lengths
    gap = person.pad_contact - np.asarray(force, dtype=np.float64) / person.pad_stiffness
    tip = thumb_points(th, person.thumb_lengths, person.thumb_base)[..., -1]
    pad_normal = -1j * np.exp(1j * thumb_directions(th)[..., -1])
    target = tip + gap * pad_normal
    rigid = l2 + l3 * np.exp(1j * np.asarray(dip, dtype=np.float64))
    r, delta = np.abs(rigid), np.angle(rigid)
    cos_beta = (np.abs(target) ** 2 - l1**2 - r**2) / (2.0 * l1 * r)
    beta = np.arccos(np.where(np.abs(cos_beta) <= 1.0, cos_beta, np.nan))
    theta1 = np.angle(target) - np.arctan2(r * np.sin(beta), l1 + r * np.cos(beta))
    return np.stack([theta1, beta - delta], axis=-1)


@dataclass(frozen=True, eq=False)
class CalibrationSession:
    """The poses a person made with the glove on, and what the glove read.

    Attributes:
        person: the person.
        theta: ``(N, 10)`` joint angles Θ [rad] (ground truth of the simulation).
        psi: ``(N, 10)`` sensor readings Ψ [rad].
        pinch: ``(N,)`` True where thumb and index touch.
    """

    person: PersonParams
    theta: NDArray[np.float64]
    psi: NDArray[np.float64]
    pinch: NDArray[np.bool_]

    def __len__(self) -> int:
        return len(self.theta)

    def subset(self, mask: NDArray[np.bool_] | NDArray[np.intp]) -> CalibrationSession:
        """The readings selected by a boolean mask or index array."""
        return CalibrationSession(self.person, self.theta[mask], self.psi[mask], self.pinch[mask])

    def split(
        self, held_out: float = 0.2, seed: int = 0
    ) -> tuple[CalibrationSession, CalibrationSession]:
        """(training, held-out) split, stratified on pinch, reproducible from ``seed``."""
        if not 0.0 < held_out < 1.0:
            raise ValueError(f"held_out must be in (0, 1), got {held_out}")
        rng = np.random.default_rng(seed)
        test = np.zeros(len(self), dtype=bool)
        for group in (np.flatnonzero(self.pinch), np.flatnonzero(~self.pinch)):
            k = round(held_out * len(group))
            test[rng.choice(group, size=k, replace=False)] = True
        return self.subset(~test), self.subset(test)


def record_session(
    person: PersonParams, n: int = 2000, pinch_fraction: float = 0.35, seed: int = 0
) -> CalibrationSession:
    """A simulated calibration session: ``n`` readings, a share of them pinch poses.

    Args:
        person: who wears the glove.
        n: number of readings (poses).
        pinch_fraction: share of pinch poses (thumb and index touching).
        seed: seeds the poses and the sensor noise.
    """
    if n < 10 or not 0.0 <= pinch_fraction <= 1.0:
        raise ValueError(f"need n >= 10 and pinch_fraction in [0, 1], got {n}, {pinch_fraction}")
    rng = np.random.default_rng(seed)
    n_pinch = round(pinch_fraction * n)
    theta = np.concatenate(
        [sample_free_poses(n - n_pinch, person, rng), sample_pinch_poses(n_pinch, person, rng)]
    )
    order = rng.permutation(n)
    theta = theta[order]
    pinch = (np.arange(n) >= n - n_pinch)[order]
    psi = sensor_readings(theta, person, rng)
    return CalibrationSession(person, theta, psi, pinch)

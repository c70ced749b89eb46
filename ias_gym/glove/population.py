"""The population of simulated persons: every parameter's distribution, with its source.

A simulated person is a hand (:class:`~ias_gym.glove.hand.PersonParams`: size, segment
lengths, how the glove sits on it) and a way of moving
(:class:`~ias_gym.glove.skills.SkillStyle`: speed, amplitude, delays, tremor, grip, range of
motion). Both are drawn here, reproducibly from the person's id, from the distributions of
:data:`PARAMETERS`; ``docs/population.md`` tabulates them with their references, and
``ias-gym population`` lists and plots a drawn set.

Each parameter is drawn by inverting its (truncated) distribution function at a uniform
number of the person's own stream (:meth:`Distribution.draw`): a truncated distribution
needs no rejection loop, and its bounds are the physical limits the models below rely on.

A population of ``n`` persons drawn with ``seed`` is the ids :func:`population_ids`
returns; an id names one person forever (the same id gives the same person on any machine:
sha256 of the id, not Python's salted ``hash()``).
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.special import ndtr, ndtri

from ias_gym.errors import InputError
from ias_gym.glove.ids import check_id

Kind = Literal["uniform", "normal", "lognormal"]


@dataclass(frozen=True)
class Distribution:
    """A one-dimensional distribution, truncated to ``[low, high]``.

    Attributes:
        kind: ``"uniform"`` on ``[low, high]``; ``"normal"`` with mean ``a`` and standard
            deviation ``b``; ``"lognormal"`` with median ``a`` and log-standard deviation ``b``.
        a, b: its parameters (unused for ``"uniform"``).
        low, high: the truncation bounds, in the parameter's unit.
    """

    kind: Kind
    a: float
    b: float
    low: float
    high: float

    def __post_init__(self) -> None:
        values = (self.a, self.b, self.low, self.high)
        if not all(math.isfinite(v) for v in values):
            raise InputError(f"distribution parameters must be finite, got {values}")
        if not self.low < self.high:
            raise InputError(f"distribution bounds must satisfy low < high, got {self.low}..")
        if self.kind != "uniform" and not self.b > 0:
            raise InputError(f"a {self.kind} distribution needs a positive spread, got {self.b}")
        if self.kind == "lognormal" and not (self.a > 0 and self.low > 0):
            raise InputError("a lognormal distribution needs a positive median and low bound")

    def _cdf(self, x: float) -> float:
        if self.kind == "normal":
            return float(ndtr((x - self.a) / self.b))
        return float(ndtr((math.log(x) - math.log(self.a)) / self.b))

    def draw(self, u: float) -> float:
        """The value at quantile ``u`` in [0, 1] of the truncated distribution."""
        if self.kind == "uniform":
            return self.low + (self.high - self.low) * u
        lo, hi = self._cdf(self.low), self._cdf(self.high)
        z = float(ndtri(lo + (hi - lo) * u))
        x = self.a + self.b * z if self.kind == "normal" else self.a * math.exp(self.b * z)
        return min(max(x, self.low), self.high)  # ndtri's last bit at the bounds

    def describe(self) -> str:
        """The distribution in a few characters, for tables (``N(1, 0.035) in [0.93, 1.07]``)."""
        if self.kind == "uniform":
            return f"U({self.low:g}, {self.high:g})"
        name = "N" if self.kind == "normal" else "logN"
        what = f"{name}({self.a:g}, {self.b:g})"
        return f"{what} in [{self.low:g}, {self.high:g}]"


@dataclass(frozen=True)
class Parameter:
    """One parameter of a simulated person: its distribution, unit and source."""

    name: str
    unit: str
    distribution: Distribution
    source: str


def _p(name: str, unit: str, kind: Kind, a: float, b: float, lo: float, hi: float, src: str):
    return Parameter(name, unit, Distribution(kind, a, b, lo, hi), src)


#: Nominal adult hand length [m] (wrist crease to the middle fingertip), the hand of scale 1:
#: the mean of the men's and the women's means below.
NOMINAL_HAND_LENGTH = 0.182
#: Share of women in the population [-].
FEMALE_SHARE = 0.5

_BODYSPACE = "Pheasant & Haslegrave, Bodyspace (3rd ed., 2006), British adults 19-65"
_BUCHHOLZ = "Buchholz, Armstrong & Goldstein, Ergonomics 35(3), 1992 (segment/hand length)"
_HUME = "Hume et al., J. Hand Surg. 15A, 1990 (active range of motion, SD 8-12 % of mean)"
_ELBLE = "Elble & Koller, Tremor (1990); McAuley & Marsden, Brain 123, 2000 (8-12 Hz)"
_VISUAL = "Saunders & Knill, Exp. Brain Res. 152, 2003; Franklin & Wolpert, Neuron 72, 2011"
_JOHANSSON = "Johansson & Westling, Exp. Brain Res. 66, 1987 (grip response 60-80 ms)"
_WESTLING = "Westling & Johansson, Exp. Brain Res. 53, 1984 (safety margin 10-40 %)"
_GLOVE = "Dipietro, Sabatini & Dario, IEEE T-SMC C 38(4), 2008 (glove donning repeatability)"
_MOVE = "Flash & Hogan, J. Neurosci. 5, 1985 (minimum jerk); inter-person spread our choice"
_OURS = "our glove model: a tolerance of the glove's mechanics (no published number)"
_THUMB = "our planar thumb model: where its CMC sits on a hand (no published number)"
_RIJPKEMA = "Rijpkema & Girard, SIGGRAPH 1991 (DIP = 2/3 PIP); spread our choice"

#: Every drawn parameter of a person, by name (``docs/population.md`` lists them).
PARAMETERS: dict[str, Parameter] = {
    p.name: p
    for p in (
        # The hand (PersonParams)
        _p("hand_length_men", "m", "normal", 0.190, 0.010, 0.160, 0.220, _BODYSPACE),
        _p("hand_length_women", "m", "normal", 0.174, 0.009, 0.147, 0.201, _BODYSPACE),
        _p("segment_ratio", "-", "normal", 1.0, 0.035, 0.93, 1.07, _BUCHHOLZ),
        _p("thumb_base_offset", "m", "uniform", 0.0, 0.0, -0.002, 0.002, _THUMB),
        _p("dip_coupling", "-", "uniform", 0.0, 0.0, 0.6, 0.75, _RIJPKEMA),
        _p("linkage_offset", "m", "uniform", 0.0, 0.0, -0.003, 0.003, _OURS),
        _p("ring_proximal", "-", "uniform", 0.0, 0.0, 0.5, 0.7, _OURS),
        _p("ring_distal", "-", "uniform", 0.0, 0.0, 0.4, 0.6, _OURS),
        _p("sensor_gain", "-", "uniform", 0.0, 0.0, 0.95, 1.05, _GLOVE),
        _p("sensor_offset", "rad", "normal", 0.0, 0.05, -0.15, 0.15, _GLOVE),
        _p("wrist_mount", "rad", "normal", 0.0, 0.06, -0.18, 0.18, _GLOVE),
        _p("crosstalk", "-", "uniform", 0.0, 0.0, 0.05, 0.15, _OURS),
        _p("pad_stiffness", "N/m", "uniform", 0.0, 0.0, 800.0, 1200.0, _OURS),
        _p("push_linkage", "rad/N", "uniform", 0.0, 0.0, 0.025, 0.04, _OURS),
        _p("push_web", "rad/N", "uniform", 0.0, 0.0, 0.03, 0.05, _OURS),
        _p("push_thumb", "rad/N", "uniform", 0.0, 0.0, 0.01, 0.02, _OURS),
        # The way of moving (SkillStyle)
        _p("speed", "-", "lognormal", 1.0, 0.1, 0.75, 1.33, _MOVE),
        _p("amplitude", "-", "lognormal", 1.0, 0.1, 0.8, 1.25, _MOVE),
        _p("start_delay", "s", "uniform", 0.0, 0.0, 0.0, 0.15, _MOVE),
        _p("visual_delay", "s", "normal", 0.12, 0.02, 0.08, 0.20, _VISUAL),
        _p("tactile_delay", "s", "normal", 0.07, 0.01, 0.05, 0.10, _JOHANSSON),
        _p("grip_margin", "-", "uniform", 0.0, 0.0, 0.1, 0.4, _WESTLING),
        _p("range_of_motion", "-", "normal", 1.0, 0.1, 0.75, 1.25, _HUME),
        _p("tremor_amplitude", "rad", "lognormal", 0.0017, 0.35, 0.0008, 0.004, _ELBLE),
        _p("tremor_hz", "Hz", "uniform", 0.0, 0.0, 8.0, 12.0, _ELBLE),
    )
}


def parameter(name: str) -> Parameter:
    """The parameter ``name`` of :data:`PARAMETERS`.

    Raises:
        KeyError: listing the names that exist.
    """
    try:
        return PARAMETERS[name]
    except KeyError:
        raise KeyError(f"unknown person parameter {name!r}; known: {sorted(PARAMETERS)}") from None


class PersonStream:
    """A person's own random numbers, one stream per purpose (``"hand"``, ``"style"``).

    Args:
        person_id: the person (checked by :func:`~ias_gym.glove.ids.check_id`).
        purpose: keeps the hand's numbers apart from the style's.
        seed: a second key (a person re-drawn with another seed is another person).
    """

    def __init__(self, person_id: str, purpose: str, seed: int = 0) -> None:
        check_id(person_id, "person_id")
        # sha256, not hash(): Python salts str hashes per process.
        digest = hashlib.sha256(f"{purpose}:{person_id}".encode()).digest()
        self.rng = np.random.default_rng([int.from_bytes(digest[:8], "little"), int(seed)])

    def draw(self, name: str) -> float:
        """One value of parameter ``name`` (:data:`PARAMETERS`)."""
        return parameter(name).distribution.draw(float(self.rng.random()))

    def draws(self, name: str, n: int) -> tuple[float, ...]:
        """``n`` independent values of parameter ``name``."""
        return tuple(self.draw(name) for _ in range(n))


def draw_hand_scale(stream: PersonStream) -> float:
    """A hand's scale (-): its length (men's or women's, :data:`FEMALE_SHARE`) over
    :data:`NOMINAL_HAND_LENGTH`."""
    female = stream.rng.random() < FEMALE_SHARE
    length = stream.draw("hand_length_women" if female else "hand_length_men")
    return length / NOMINAL_HAND_LENGTH


def check_population(n: object, seed: object) -> tuple[int, int]:
    """``(n, seed)`` of a population draw, checked.

    Raises:
        InputError: ``n`` is not a whole number >= 1 or ``seed`` not a whole number >= 0.
    """
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
        raise InputError(f"population size {n!r} must be a whole number >= 1")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise InputError(f"population seed {seed!r} must be a whole number >= 0")
    return int(n), int(seed)


def population_ids(n: int, seed: int) -> list[str]:
    """The ids of ``n`` persons drawn from the population with ``seed``.

    Each id is ``pop<seed>-<k>`` with a short hash, so that ids of different seeds never
    coincide and the k-th person of a seed is the same everywhere.

    Raises:
        InputError: as :func:`check_population`.
    """
    n, seed = check_population(n, seed)
    ids = []
    for k in range(n):
        tag = hashlib.sha256(f"population:{seed}:{k}".encode()).hexdigest()[:6]
        ids.append(f"pop{seed}-{k:03d}-{tag}")
    return ids

"""Impairment specs: ``NAME``, ``NAME:KEY=VALUE[,KEY=VALUE]``, ``A+B`` and ``sampled``.

An impairment is one family or a combination of families, each with its parameters
(:data:`FAMILIES`: every key's unit, allowed range, default and the range ``sampled`` draws
from, with the source of the range). A spec string names it::

    tremor                      # the family at its defaults
    tremor:hz=5,amplitude_rad=0.04
    weak_grip:fingers=thumb
    biased_calibration:rad=-0.08,fingers=index
    biased_calibration:rad=+0.08  # a sign on a value; a + before a name joins families
    tremor+weak_grip:rad=0.1    # a combination: every part applies
    sampled                     # a family and its parameters drawn per session
    none

:func:`parse_impairment` turns a spec into an :class:`Impairment` (a bad name, key or value
is an :class:`~ias_gym.errors.InputError` that names it and the allowed range);
:func:`expand_specs` expands the CLI's ``all``; :meth:`Impairment.draw` resolves
``sampled`` from a random stream. Pure Python: the env (:mod:`ias_gym.envs.glove_assist`) applies
the parts.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from ias_gym.errors import InputError

Value = float | str


@dataclass(frozen=True)
class Key:
    """One parameter of a family.

    Attributes:
        unit: its unit (``""`` for a choice).
        default: the value of the bare family name.
        low, high: the allowed range (numbers; inclusive).
        sample: the range ``sampled`` draws from uniformly (numbers), or the choices it draws
            from (a choice key: its allowed values).
    """

    unit: str
    default: Value
    low: float = -math.inf
    high: float = math.inf
    sample: tuple[Value, ...] = ()

    @property
    def is_choice(self) -> bool:
        """The key takes one of :attr:`sample`'s names, not a number."""
        return isinstance(self.default, str)

    def describe(self) -> str:
        """The allowed values, for an error message."""
        if self.is_choice:
            return "|".join(str(v) for v in self.sample)
        return f"{self.low:g}..{self.high:g} {self.unit}".rstrip()


FINGERS = ("index", "thumb", "both")

#: Every family's keys. Ranges, and where they come from:
#:
#: - ``tremor``: ``hz`` 4-12 Hz, the frequencies of pathological tremors (parkinsonian rest
#:   tremor 4-6 Hz, essential tremor 4-12 Hz: Deuschl, Bain & Brin 1998, the Movement
#:   Disorder Society's consensus statement on tremor); ``amplitude_rad`` up to 0.1 rad
#:   (about 1 cm at the fingertips, the mild-to-moderate grades of the Fahn-Tolosa-Marin
#:   rating scale), sampled from 0.02 rad (1 deg) on;
#: - ``weak_grip``: ``rad``, how much less the pinch closes on index MCP and thumb flexion
#:   (the joint-space size of a grip force lowered by paresis, up to 0.15 rad, about the
#:   pinch's whole squeeze travel), ``fingers`` which of them;
#: - ``lag``: ``s``, 50-300 ms, the delays of networked teleoperation at which operators'
#:   performance degrades measurably (Sheridan & Ferrell 1963; Lane et al. 2002);
#: - ``biased_calibration``: ``rad``, signed (> 0 opens the pinch), up to 0.15 rad (9 deg), the
#:   order of the joint-angle errors reported for calibrated data gloves (several degrees:
#:   Dipietro, Sabatini & Dario 2008, "A survey of glove-based systems"), ``fingers``;
#: - ``hand_size``: ``scale`` 0.8-1.25, adult hand lengths from the 1st to the 99th
#:   percentile about the population's median (hand anthropometry: Pheasant & Haslegrave,
#:   "Bodyspace", 3rd ed., 2006: the 5th-95th of women and men span about 0.85-1.15);
#: - ``stops``: ``at``, the share of the skill's own motion the operator performs before
#:   holding still ("the operator only gives the goal"), 0-1, sampled 0.2-0.8.
FAMILIES: dict[str, dict[str, Key]] = {
    "tremor": {
        "hz": Key("Hz", 10.0, 4.0, 12.0, (4.0, 12.0)),
        "amplitude_rad": Key("rad", 0.06, 0.0, 0.1, (0.02, 0.1)),
    },
    "weak_grip": {
        "rad": Key("rad", 0.08, 0.0, 0.15, (0.04, 0.15)),
        "fingers": Key("", "both", sample=FINGERS),
    },
    "lag": {"s": Key("s", 0.1, 0.0, 0.3, (0.05, 0.3))},
    "biased_calibration": {
        "rad": Key("rad", 0.10, -0.15, 0.15, (-0.15, 0.15)),
        "fingers": Key("", "both", sample=FINGERS),
    },
    "hand_size": {"scale": Key("", 1.2, 0.8, 1.25, (0.8, 1.25))},
    "stops": {"at": Key("", 0.4, 0.0, 1.0, (0.2, 0.8))},
}
#: Each family's size key: the one the legacy ``strength`` sets.
STRENGTH_KEY: dict[str, str] = {
    "tremor": "amplitude_rad",
    "weak_grip": "rad",
    "lag": "s",
    "biased_calibration": "rad",
    "hand_size": "scale",
    "stops": "at",
}
#: Spec words that are no family: no impairment, and one family drawn per session.
NONE, SAMPLED = "none", "sampled"
#: The CLI's word for every family at its defaults (:func:`expand_specs`).
ALL = "all"


@dataclass(frozen=True)
class Family:
    """One family with its parameters (every key of :data:`FAMILIES` set).

    Attributes:
        name: the family.
        params: ``((key, value), ...)`` in :data:`FAMILIES`' order.
    """

    name: str
    params: tuple[tuple[str, Value], ...]

    def __getitem__(self, key: str) -> Value:
        return dict(self.params)[key]

    def number(self, key: str) -> float:
        """A numeric parameter."""
        value = self[key]
        assert isinstance(value, float)
        return value

    @property
    def strength(self) -> float:
        """The family's size (:data:`STRENGTH_KEY`)."""
        return self.number(STRENGTH_KEY[self.name])

    def spec(self) -> str:
        """The canonical spec of this family, every key written out."""
        keys = ",".join(
            f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in self.params
        )
        return f"{self.name}:{keys}"


@dataclass(frozen=True)
class Impairment:
    """An impairment: no family (``none``), one, several at once, or ``sampled``.

    Attributes:
        spec: the spec it was made from, as given.
        families: its parts (empty: none).
        sampled: a family is drawn per session (:meth:`draw`); ``families`` is empty.
    """

    spec: str
    families: tuple[Family, ...] = ()
    sampled: bool = False

    @classmethod
    def make(cls, name: str, strength: float | None = None) -> Impairment:
        """A spec, or a bare family name with its size (:data:`STRENGTH_KEY`) set to
        ``strength`` (None: its default).

        Raises:
            InputError: as :func:`parse_impairment`; a ``strength`` with a spec that is no
                bare family name.
        """
        if strength is None:
            return parse_impairment(name)
        if name not in FAMILIES:
            raise InputError(
                f"strength is the size of one family; give it in the spec instead "
                f"({name!r} is no family name: {', '.join(FAMILIES)})"
            )
        return parse_impairment(f"{name}:{STRENGTH_KEY[name]}={float(strength)!r}")

    @property
    def name(self) -> str:
        """``none``, ``sampled``, the family's name, or the families' joined by ``+``."""
        if self.sampled:
            return SAMPLED
        return "+".join(f.name for f in self.families) or NONE

    @property
    def strength(self) -> float:
        """The size of a one-family impairment (0 for none).

        Raises:
            ValueError: a combination or ``sampled`` has no one size.
        """
        if not self.families and not self.sampled:
            return 0.0
        if len(self.families) != 1:
            raise ValueError(f"impairment {self.spec!r} has no single strength")
        return self.families[0].strength

    def family(self, name: str) -> Family | None:
        """The part of family ``name``, or None."""
        return next((f for f in self.families if f.name == name), None)

    def draw(self, rng: np.random.Generator) -> Impairment:
        """A concrete impairment: for ``sampled``, one family (uniformly) with its
        parameters drawn uniformly from their sample ranges (:data:`FAMILIES`); anything
        else is returned as it is."""
        if not self.sampled:
            return self
        name = str(rng.choice(list(FAMILIES)))
        params: list[tuple[str, Value]] = []
        for key, k in FAMILIES[name].items():
            if k.is_choice:
                params.append((key, str(rng.choice(list(k.sample)))))
            else:
                lo, hi = (float(v) for v in k.sample)
                params.append((key, round(float(rng.uniform(lo, hi)), 4)))
        family = Family(name, tuple(params))
        return Impairment(family.spec(), (family,))


def _value(family: str, key: str, text: str) -> Value:
    k = FAMILIES[family][key]
    if k.is_choice:
        if text not in k.sample:
            raise InputError(f"impairment {family}: {key}={text!r} is not one of {k.describe()}")
        return text
    try:
        value = float(text)
    except ValueError:
        raise InputError(
            f"impairment {family}: {key}={text!r} is not a number (allowed {k.describe()})"
        ) from None
    if not (math.isfinite(value) and k.low <= value <= k.high):
        raise InputError(f"impairment {family}: {key}={text} is out of range ({k.describe()})")
    return value


def _family(text: str) -> Family:
    name, _, rest = text.partition(":")
    name = name.strip()
    if name not in FAMILIES:
        raise InputError(
            f"impairment {name!r} is not known; choose one of {NONE}, {SAMPLED}, "
            f"{', '.join(FAMILIES)} (or join families with +)"
        )
    keys = FAMILIES[name]
    given: dict[str, Value] = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, eq, value = item.partition("=")
        key = key.strip()
        if not eq or key not in keys:
            raise InputError(
                f"impairment {name}: {item!r} is not KEY=VALUE with a key of "
                f"{', '.join(f'{k}={v.describe()}' for k, v in keys.items())}"
            )
        if key in given:
            raise InputError(f"impairment {name}: {key} is given twice")
        given[key] = _value(name, key, value.strip())
    if ":" in text and not given:
        raise InputError(f"impairment {text!r}: nothing after ':' (give KEY=VALUE or no ':')")
    return Family(name, tuple((k, given.get(k, v.default)) for k, v in keys.items()))


#: A ``+`` that joins families: one before a family's name, not a value's sign (``rad=+0.1``).
_JOIN = re.compile(r"\+(?=\s*[A-Za-z_])")


def parse_impairment(spec: str) -> Impairment:
    """The impairment a spec names (module docstring).

    Args:
        spec: ``none``, ``sampled``, or families joined by ``+``, each ``NAME`` or
            ``NAME:KEY=VALUE[,KEY=VALUE]``.

    Raises:
        InputError: an unknown family or key, a value that is no number or out of its range,
            a key given twice, a family twice in a combination, or ``none``/``sampled``
            combined.
    """
    if not isinstance(spec, str) or not spec.strip():
        raise InputError(f"impairment spec must be a non-empty string, got {spec!r}")
    text = spec.strip()
    if text in (NONE, SAMPLED):
        return Impairment(text, (), sampled=text == SAMPLED)
    parts = [p.strip() for p in _JOIN.split(text)]
    if any(p in (NONE, SAMPLED, ALL) for p in parts):
        raise InputError(f"impairment {spec!r}: {NONE}, {SAMPLED} and {ALL} stand alone")
    families = tuple(_family(p) for p in parts)
    names = [f.name for f in families]
    if len(set(names)) != len(names):
        raise InputError(f"impairment {spec!r} names a family twice")
    return Impairment(text, families)


def expand_specs(specs: Iterable[str]) -> list[str]:
    """The CLI's ``--impairment`` values with ``all`` replaced by every family's name (in
    :data:`FAMILIES`' order), each checked (:func:`parse_impairment`); duplicates dropped."""
    out: list[str] = []
    for spec in specs:
        for s in list(FAMILIES) if spec.strip() == ALL else [spec]:
            parse_impairment(s)
            if s not in out:
                out.append(s)
    return out


def family_table(families: Mapping[str, Mapping[str, Key]] = FAMILIES) -> list[dict[str, str]]:
    """Rows ``{family, key, unit, default, allowed, sampled}`` for docs and ``--help``."""
    rows = []
    for name, keys in families.items():
        for key, k in keys.items():
            sampled = (
                "|".join(map(str, k.sample))
                if k.is_choice
                else f"{float(k.sample[0]):g}..{float(k.sample[1]):g}"
            )
            rows.append(
                {
                    "family": name,
                    "key": key,
                    "unit": k.unit,
                    "default": str(k.default) if k.is_choice else f"{k.default:g}",
                    "allowed": k.describe(),
                    "sampled": sampled,
                }
            )
    return rows

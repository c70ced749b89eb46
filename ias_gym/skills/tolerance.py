"""How close a transferred skill must stay to its demonstration: the person's repeatability.

A robot hand that executes a demonstrated skill succeeds when it holds the pen and its
execution is as close to the demonstration as another demonstration of the same person
would be. "As close" is measured by three numbers, the ones ``IAS-PenSkill-v0`` measures
of an execution (:func:`reference_distance` computes them between two references on the
env's own grid):

- the RMS angle between the pen's axis and the reference's [rad],
- the RMS distance of the pen's centre from the reference's [m],
- the mean relative error of the grasp margin, ``|m - m_ref| / m_ref`` [-].

The tolerances are fitted by ``train/transfer_tolerances.py`` on development persons of the
population, each demonstrating every skill class several times: per class, the same
quantile of the three distances over the ordered pairs of one person's repetitions
(cross-validated over groups of persons; the file records the quantile, the persons'
draw and the held-out coverage). The distances are taken on unscaled references, and a
hand's tolerance is scaled like its reference: positions by the translation scale, angles
by the rotation scale. A skill of a class the fit never saw gets the tolerance pooled over
every class (key ``"*"``).

The fitted tolerances are the JSON file :data:`TOLERANCE_FILE` in ``ias_gym.assets``; it is
read with :func:`json.loads` and checked, never executed.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.resources
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ias_gym.envs.pen_skill_env import MARGIN_CLIP, PenSkillConfig
from ias_gym.envs.skill_reference import SkillReference
from ias_gym.errors import InputError

#: The fitted tolerances shipped in ``ias_gym.assets``.
TOLERANCE_FILE = "transfer_tolerances.json"
#: The key of the tolerance pooled over every skill class.
POOLED = "*"


@dataclass(frozen=True)
class Tolerance:
    """How far an execution may stay from its demonstration and still succeed.

    Attributes:
        rotation: RMS axis angle [rad].
        position: RMS pen-centre distance [m].
        margin: mean relative grasp-margin error [-].
    """

    rotation: float
    position: float
    margin: float

    def __post_init__(self) -> None:
        for name in ("rotation", "position", "margin"):
            value = getattr(self, name)
            if not (isinstance(value, float | int) and math.isfinite(value) and value > 0):
                raise InputError(f"a tolerance's {name} must be a finite number > 0, got {value!r}")

    def scaled(self, scale: float, scale_rotation: float) -> Tolerance:
        """The tolerance of a reference scaled into a hand's workspace (positions by
        ``scale``, angles by ``scale_rotation``; the margin is a ratio and keeps its value)."""
        return Tolerance(
            rotation=self.rotation * scale_rotation,
            position=self.position * scale,
            margin=self.margin,
        )


def _grid(reference: SkillReference, duration: float, settle_time: float) -> np.ndarray:
    """The samples of ``reference`` the env compares an execution with: steps ``1 .. N``
    of a ``duration`` episode at or after ``settle_time`` (the pose held after the end)."""
    steps = np.arange(1, round(duration / reference.dt) + 1)
    steps = steps[steps * reference.dt >= settle_time - 1e-9]
    return np.minimum(steps, reference.length - 1)


def reference_distance(
    executed: SkillReference,
    reference: SkillReference,
    duration: float = PenSkillConfig.duration,
    settle_time: float = PenSkillConfig.settle_time,
) -> tuple[float, float, float]:
    """How far ``executed`` stays from ``reference``, measured as the env measures a run.

    Args:
        executed: the motion and margin that were performed (e.g. another demonstration).
        reference: the one it is judged against (its margin is the denominator).
        duration: the episode's length [s]; settle_time: the errors ignore the time before
            it [s] (the env's defaults).

    Returns:
        ``(rotation [rad], position [m], margin [-])``: RMS axis angle, RMS centre
        distance, mean ``|min(m, 10) - m_ref| / m_ref``.

    Raises:
        InputError: the two are sampled at different periods.
    """
    if not math.isclose(executed.dt, reference.dt):
        raise InputError(
            f"references sampled every {executed.dt} s and {reference.dt} s cannot be compared"
        )
    a, b = _grid(executed, duration, settle_time), _grid(reference, duration, settle_time)
    cos = np.clip(np.sum(executed.axis[a] * reference.axis[b], axis=1), -1.0, 1.0)
    rotation = math.sqrt(float(np.mean(np.arccos(cos) ** 2)))
    offset = executed.position[a] - reference.position[b]
    position = math.sqrt(float(np.mean(np.sum(offset**2, axis=1))))
    m_ref = reference.margin[b]
    margin = float(np.mean(np.abs(np.minimum(executed.margin[a], MARGIN_CLIP) - m_ref) / m_ref))
    return rotation, position, margin


def still_reference(reference: SkillReference) -> SkillReference:
    """A weak execution of ``reference``: the pen held still at its start pose, the
    demonstrated margin kept (the success test must fail it where the skill moves the pen
    further than the person repeats it)."""
    zero = np.zeros_like(reference.position)
    start = np.repeat(reference.position[:1], reference.length, axis=0)
    axis = np.repeat(reference.axis[:1], reference.length, axis=0)
    return dataclasses.replace(
        reference,
        position=start,
        velocity=zero,
        acceleration=zero,
        axis=axis,
        omega=zero,
        alpha=zero,
    )


def constant_margin_reference(reference: SkillReference, margin: float) -> SkillReference:
    """A weak execution of ``reference``: its motion with a constant grasp margin [-]."""
    return dataclasses.replace(reference, margin=np.full(reference.length, float(margin)))


def _check(data: Any, where: str) -> dict[str, Tolerance]:
    """The class -> tolerance table of a tolerance file's contents (checked)."""
    classes = data.get("classes") if isinstance(data, dict) else None
    if not isinstance(classes, dict) or POOLED not in classes:
        raise InputError(
            f"{where} is not a tolerance file: it needs a 'classes' object with a "
            f"'{POOLED}' entry; write it with train/transfer_tolerances.py"
        )
    table = {}
    for name, entry in classes.items():
        try:
            table[str(name)] = Tolerance(
                rotation=math.radians(entry["rot_rms_deg"]),
                position=entry["pos_rms_mm"] / 1000.0,
                margin=entry["margin_err_rel"],
            )
        except (KeyError, TypeError) as exc:
            raise InputError(
                f"{where}: class {name!r} needs rot_rms_deg, pos_rms_mm and margin_err_rel "
                f"numbers ({exc})"
            ) from None
        except InputError as exc:
            raise InputError(f"{where}: class {name!r}: {exc}") from None
    return table


def load_tolerances(path: str | Path | None = None) -> dict[str, Tolerance]:
    """The fitted tolerances by skill class (``"*"``: pooled over every class).

    Args:
        path: a tolerance file (default: the one shipped in ``ias_gym.assets``).

    Raises:
        InputError: the file is missing, not JSON, or not a tolerance table.
    """
    if path is None:
        return dict(_shipped())
    where = Path(path)
    try:
        data = json.loads(where.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"tolerance file {where} does not exist") from None
    except (OSError, ValueError) as exc:
        raise InputError(f"tolerance file {where} cannot be read as JSON: {exc}") from None
    return _check(data, str(where))


@functools.cache
def _shipped() -> dict[str, Tolerance]:
    text = (importlib.resources.files("ias_gym.assets") / TOLERANCE_FILE).read_text("utf-8")
    return _check(json.loads(text), f"ias_gym/assets/{TOLERANCE_FILE}")


def skill_tolerance(name: str, table: dict[str, Tolerance] | None = None) -> Tolerance:
    """The unscaled tolerance of a skill class (the pooled one for a class never fitted).

    Args:
        name: the skill's name (its class, e.g. ``"seesaw_slow"``).
        table: from :func:`load_tolerances` (default: the shipped one).
    """
    tolerances = _shipped() if table is None else table
    return tolerances.get(name, tolerances[POOLED])

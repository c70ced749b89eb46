"""What ``IAS-GloveGrasp-v0`` takes from the glove: its default glove and a reading's Θ.

:func:`default_glove` is the env's glove when none is given: the simulated person doing the
pen's pinch-lift (and the skill) on a :class:`~ias_gym.glove.device.SimulatedGlove`, in the
loop (:func:`person_in_the_loop`, a :class:`~ias_gym.glove.closed_loop.ClosedLoopOperator`)
or by the open script.
:func:`read_theta` turns one reading into the hand's joint targets: the calibrated joint
angles Θ = f(Ψ) [rad], clipped to the joint ranges, non-finite ones replaced.
"""

from __future__ import annotations

import mujoco
import numpy as np
from numpy.typing import NDArray

from ias_gym.glove.calibration import Calibration
from ias_gym.glove.closed_loop import ClosedLoopOperator
from ias_gym.glove.device import GloveDevice, SimulatedGlove
from ias_gym.glove.hand import JOINT_HIGH, JOINT_LOW, PersonParams
from ias_gym.glove.operator import FromPreShape, ScriptedOperator, pen_operator, skill_operator

FloatArray = NDArray[np.float64]


def default_glove(
    model: mujoco.MjModel, person: PersonParams, skill: str | None, operator: str, seed: int
) -> tuple[GloveDevice, ClosedLoopOperator | None]:
    """The simulated ``person`` doing the pen's pinch-lift (and ``skill``) on a
    :class:`SimulatedGlove` seeded ``seed``, and the person in the loop (``None`` for the
    open ``operator="script"``).

    Args:
        model: the compiled glove scene (the pen's radius, weight and friction are read
            from it).
        person: the glove's wearer.
        skill: the skill after the pinch-lift (``None``: the pinch-lift alone).
        operator: ``"closed_loop"`` or ``"script"``
            (:data:`~ias_gym.envs.glove_grasp_config.OPERATORS`).
        seed: the glove's noise seed.
    """
    # The operator pinches the scene's pen: its radius read from the compiled model.
    pen_geom = model.geom("pen").id
    radius = float(model.geom_size[pen_geom, 0])
    plan = pen_operator(person, radius) if skill is None else skill_operator(person, radius, skill)
    if operator == "script":
        return SimulatedGlove(person, FromPreShape(plan), seed), None
    closed_loop = person_in_the_loop(model, plan, person)
    return SimulatedGlove(person, closed_loop, seed), closed_loop


def person_in_the_loop(
    model: mujoco.MjModel, plan: ScriptedOperator, person: PersonParams
) -> ClosedLoopOperator:
    """``person`` doing ``plan`` (script time; an impaired plan too) in the loop of the glove
    scene ``model``: gripping the pen by its weight and friction, read from the model."""
    pen = model.body("pen").id
    weight = float(model.body_subtreemass[pen] * -model.opt.gravity[2])
    friction = float(model.geom_friction[model.geom("pen").id, 0])
    return ClosedLoopOperator(plan, person, object_weight=weight, friction=friction)


def read_theta(
    glove: GloveDevice, calibration: Calibration, fallback: FloatArray
) -> tuple[FloatArray, bool]:
    """Calibrated joint angles Θ [rad] of a new reading, clipped to the joint ranges, and
    whether the calibration gave finite numbers.

    NaN passes ``np.clip`` and would reach MuJoCo's ``ctrl`` (which then warns and zeroes
    it, so the hand goes limp without a word): non-finite entries are replaced by
    ``fallback`` (the last finite targets) and reported.
    """
    theta = np.asarray(calibration.predict(glove.read().psi), dtype=np.float64)
    finite = np.isfinite(theta)
    ok = bool(finite.all())
    if not ok:
        theta = np.where(finite, theta, fallback)
    return np.minimum(np.maximum(theta, JOINT_LOW), JOINT_HIGH), ok  # np.clip, cheaper

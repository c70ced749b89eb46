"""The reward of ``IAS-GloveGrasp-v0``: its terms, their kernels and widths, and the
tolerance of the ``lift_place`` skill's success.

:func:`reward_terms` is the env's reward of one step (the sum of its terms; the env's
docstring, "Rewards", says what each means), from what the env measured of the pen;
:class:`~ias_gym.envs.glove_grasp.GloveGraspEnv` reports each term as
``info["reward_<name>"]``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ias_gym.envs.glove_grasp_config import GloveGraspConfig

#: ``lift_place`` succeeds when the pen, lifted before, is back within this height of its
#: start [m] (on its support) and both fingers still hold it.
PLACE_TOLERANCE = 0.005

#: Reward term names (info keys ``reward_<name>``).
REWARD_TERMS = ("lift", "track", "pinch", "effort")
#: Widths of the skill reward's kernels: the pen's height [m] and tilt [rad] at which a term
#: falls to half its weight (a person's own repeatability: lifts end within about +-5 mm,
#: tilts within about +-3 deg of each other).
HEIGHT_TOLERANCE = 0.005
TILT_TOLERANCE = 0.05


def tolerance(error: float, width: float) -> float:
    """1 at no error, 1/2 at ``width``, towards 0 beyond (a bounded Cauchy kernel, as
    dm_control's ``rewards.tolerance`` with a Lorentzian sigmoid)."""
    return 1.0 / (1.0 + (error / width) ** 2)


def reward_terms(
    config: GloveGraspConfig,
    action: NDArray[np.float64],
    dz: float,
    pinched: bool,
    skill_errors: tuple[float, float] | None,
) -> dict[str, float]:
    """The weighted reward terms of one step, by :data:`REWARD_TERMS` name.

    Args:
        config: the env's settings (the weights, ``lift_height``).
        action: the step's action, clipped to [-1, 1].
        dz: the pen's height gain over its start [m].
        pinched: both index and thumb touch the pen.
        skill_errors: with a skill, the pen's height [m] and tilt [rad] minus those the
            person's plan means now; ``None`` without a skill (the pinch-lift alone: the
            lift term grows up to ``lift_height``, the track term is 0).
    """
    if skill_errors is None:  # the pinch-lift alone: up to lift_height
        lift, track = min(max(dz / config.lift_height, 0.0), 1.0), 0.0
    else:  # the skill's intended object motion, as this person means to do it
        lift = tolerance(skill_errors[0], HEIGHT_TOLERANCE)
        track = tolerance(skill_errors[1], TILT_TOLERANCE)
    return {
        "lift": config.lift_weight * lift,
        "track": config.track_weight * track,
        "pinch": config.contact_weight * float(pinched),
        # np.mean's own sum and division, without its Python-level wrapper (hot path).
        "effort": -config.effort_weight * (float(np.add.reduce(action * action)) / action.size),
    }

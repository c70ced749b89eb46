"""Closed-loop tests that hold on any machine: the same rollout from nearby starts.

A closed-loop rollout (the controller or a trained policy acting on the simulation) is
chaotic: another CPU or BLAS changes the last bits of a step and the trajectories part. A
test that passes from the one start this machine computed may sit on a knife edge that
another machine falls off. :func:`perturbed_starts` gives a seed's own start and
``N_PERTURBED`` starts whose ``qpos`` differ from it by about ``PERTURBATION``, what another
machine does to a rollout; every test that runs the controller or a policy for more than a few
steps checks its property from each of them.
"""

from __future__ import annotations

from ias_gym.glove.hand import PersonParams
from ias_gym.glove.population import PARAMETERS, population_ids
from ias_gym.glove.skills import SkillStyle
from ias_gym.perturbed_starts import N_PERTURBED, PERTURBATION, perturbed_starts

__all__ = ["N_PERTURBED", "PERTURBATION", "perturbed_starts", "typical_person"]


def typical_person(seed: int = 0) -> str:
    """The first person drawn with ``seed`` whose hand and movement lie within one standard
    deviation of the population's means (hand scale, range of motion, speed, amplitude): a
    person chosen by a rule, not by an outcome, for tests of a mechanism on an ordinary hand
    (the spread of the population is measured by ``train/completion_table.py``)."""
    for person_id in population_ids(200, seed):
        hand, style = PersonParams.sample(person_id), SkillStyle.sample(person_id)
        values = {
            "hand_scale": abs(hand.hand_scale - 1.0) / 0.07,
            "range_of_motion": abs(hand.range_of_motion - 1.0)
            / PARAMETERS["range_of_motion"].distribution.b,
            "speed": abs(style.speed - 1.0) / 0.1,
            "amplitude": abs(style.amplitude - 1.0) / 0.1,
        }
        if max(values.values()) <= 1.0:
            return person_id
    raise LookupError(f"no typical person among the first 200 of seed {seed}")

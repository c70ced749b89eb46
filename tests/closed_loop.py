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

from ias_gym.evaluation import N_PERTURBED, PERTURBATION, perturbed_starts

__all__ = ["N_PERTURBED", "PERTURBATION", "perturbed_starts"]

"""The randomised dynamics of DAgger's training episodes and their reset seeds.

Every training episode of :func:`~ias_gym.learning.dagger.dagger` (and of
:func:`~ias_gym.learning.expert_labelling.expert_dataset`) draws one family of the
robustness suite (:data:`ias_gym.robustness.DISTURBANCES`) uniformly, and that family's
parameters uniformly from :class:`Randomisation`'s ranges, which contain the suite's fixed
classes with a margin (the suite's class in the last column):

============================  ==================================  ==================
family                        env kwargs (uniform)                suite class
============================  ==================================  ==================
``nominal``                   none                                ``nominal``
``friction``                  ``friction_scale`` 0.6 - 1.4        0.7, 1.3
``mass``                      ``mass_scale`` 0.6 - 1.4            0.7, 1.3
``push``                      ``push_force`` 0.1 - 0.4 N,         0.3 N, 0.05 s
                              ``push_duration`` 0.03 - 0.07 s
``observation_noise``         x 0 - 1.5 of the class's sigmas     x 1 (0.02 N,
                              (force, joint angle, velocity)      1 mrad, 0.02 rad/s)
``action_delay``              ``action_delay`` 0 - 2 steps        1 step
``action_noise``              ``action_noise`` 0 - 0.003          0.002
``internal_force_steps``      ``internal_force_step`` 0 - 0.15 N  0.1 N
``combined``                  all of the above at once, each      none
                              drawn from its range
============================  ==================================  ==================

The default draws one disturbance at a time (:data:`SINGLE_FAMILIES`). ``combined`` is the
domain randomisation of Tobin et al. (2017) and OpenAI et al. (2019), every parameter drawn
in every episode: each such episode has a push, action noise and a model error, so the
states a learner must recover from are far more often in the data than one family in eight
puts them (``Randomisation(families=...)`` with a name repeated weights it).

An episode's dynamics and reset seed depend only on the run's seed and the episode's
index (:func:`episode_dynamics`), and every training reset seed is below
:data:`HELD_OUT_SEED_START`, so evaluation seeds from there on are never trained on.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np

from ias_gym.errors import InputError
from ias_gym.robustness import DISTURBANCES

#: Training reset seeds are drawn below this; evaluate on seeds from here on (held out).
HELD_OUT_SEED_START = 100_000
#: The families :data:`DEFAULT_RANDOMISATION` draws from: the robustness suite's classes,
#: grouped, one disturbance at a time.
SINGLE_FAMILIES: tuple[str, ...] = (
    "nominal",
    "friction",
    "mass",
    "push",
    "observation_noise",
    "action_delay",
    "action_noise",
    "internal_force_steps",
)
#: Every family a training episode can draw: the single ones and ``combined`` (all at once).
FAMILIES: tuple[str, ...] = (*SINGLE_FAMILIES, "combined")
#: The suite's observation-noise class: the sigmas a draw of that family scales.
OBSERVATION_NOISE: Mapping[str, float] = DISTURBANCES["observation_noise"]


@dataclass(frozen=True)
class Randomisation:
    """The ranges training dynamics are drawn from (see the module docstring's table).

    Each range is ``(low, high)``, drawn uniformly (``action_delay``: a whole number of
    steps, both ends included).

    Attributes:
        families: the families drawn from, uniformly (names of :data:`FAMILIES`).
        friction_scale: the pen's friction coefficient x this [-].
        mass_scale: the pen's mass and inertia x this [-].
        push_force: the push's magnitude [N].
        push_duration: the push's duration [s].
        observation_noise_scale: factor on the suite's observation-noise sigmas [-].
        action_delay: control steps between an action and its effect [-].
        action_noise: sigma of the noise on the normalised action [-].
        internal_force_step: size of the internal-force reference steps [N].
    """

    families: tuple[str, ...] = SINGLE_FAMILIES
    friction_scale: tuple[float, float] = (0.6, 1.4)
    mass_scale: tuple[float, float] = (0.6, 1.4)
    push_force: tuple[float, float] = (0.1, 0.4)
    push_duration: tuple[float, float] = (0.03, 0.07)
    observation_noise_scale: tuple[float, float] = (0.0, 1.5)
    action_delay: tuple[int, int] = (0, 2)
    action_noise: tuple[float, float] = (0.0, 0.003)
    internal_force_step: tuple[float, float] = (0.0, 0.15)

    def __post_init__(self) -> None:
        unknown = [f for f in self.families if f not in FAMILIES]
        if unknown or not self.families:
            raise InputError(
                f"unknown randomisation families {unknown or list(self.families)}; "
                f"known: {', '.join(FAMILIES)}"
            )
        for name in (
            "friction_scale",
            "mass_scale",
            "push_force",
            "push_duration",
            "observation_noise_scale",
            "action_delay",
            "action_noise",
            "internal_force_step",
        ):
            low, high = getattr(self, name)
            if not (math.isfinite(low) and math.isfinite(high) and 0 <= low <= high):
                raise InputError(
                    f"{name} range must be finite with 0 <= low <= high, got {low, high}"
                )
        if self.friction_scale[0] <= 0 or self.mass_scale[0] <= 0 or self.push_duration[0] <= 0:
            raise InputError("friction_scale, mass_scale and push_duration ranges must be > 0")

    def sample(self, rng: np.random.Generator) -> tuple[str, dict[str, Any]]:
        """One episode's ``(family, env kwargs)``."""
        family = self.families[int(rng.integers(len(self.families)))]

        def uniform(bounds: tuple[float, float]) -> float:
            return float(rng.uniform(bounds[0], bounds[1]))

        def draw(name: str) -> dict[str, Any]:
            if name == "friction":
                return {"friction_scale": uniform(self.friction_scale)}
            if name == "mass":
                return {"mass_scale": uniform(self.mass_scale)}
            if name == "push":
                return {
                    "push_force": uniform(self.push_force),
                    "push_duration": uniform(self.push_duration),
                }
            if name == "observation_noise":
                scale = uniform(self.observation_noise_scale)
                return {key: scale * sigma for key, sigma in OBSERVATION_NOISE.items()}
            if name == "action_delay":
                low, high = self.action_delay
                return {"action_delay": int(rng.integers(low, high + 1))}
            if name == "action_noise":
                return {"action_noise": uniform(self.action_noise)}
            if name == "internal_force_steps":
                return {"internal_force_step": uniform(self.internal_force_step)}
            return {}  # nominal

        if family != "combined":
            return family, draw(family)
        kwargs: dict[str, Any] = {}
        for name in SINGLE_FAMILIES:  # every disturbance at once, in a fixed order
            kwargs.update(draw(name))
        return family, kwargs


#: The default ranges (the module docstring's table).
DEFAULT_RANDOMISATION = Randomisation()
#: No randomisation: every episode nominal.
NOMINAL = Randomisation(families=("nominal",))


@dataclass(frozen=True)
class EpisodeDynamics:
    """What one training episode runs under.

    Attributes:
        family: the drawn family (a name of :data:`FAMILIES`).
        env_kwargs: the env kwargs it was drawn as.
        seed: the episode's reset seed (< :data:`HELD_OUT_SEED_START`).
    """

    family: str
    env_kwargs: dict[str, Any]
    seed: int


def episode_dynamics(
    seed: int, episode: int, randomisation: Randomisation = DEFAULT_RANDOMISATION
) -> EpisodeDynamics:
    """The dynamics and reset seed of training episode ``episode`` of the run ``seed``.

    A function of ``(seed, episode)`` alone (its own generator), so a run is reproducible
    and any episode can be recomputed.

    Args:
        seed: the run's seed (>= 0).
        episode: the episode's index in the run (>= 0).
        randomisation: the ranges.
    """
    rng = np.random.default_rng([seed, episode, 0xDA99E])
    family, kwargs = randomisation.sample(rng)
    return EpisodeDynamics(family, kwargs, int(rng.integers(HELD_OUT_SEED_START)))


class RandomisedDynamicsEnv(gym.Env[Any, Any]):
    """A pen task whose every episode runs under newly drawn dynamics, for RL agents.

    Reset ``k`` of the run ``seed`` makes the env of
    :func:`episode_dynamics` ``(seed, k)`` (its env kwargs on top of ``env_kwargs``) and
    resets it with that draw's seed (below :data:`HELD_OUT_SEED_START`), as DAgger's
    training episodes do; a seed passed to :meth:`reset` starts the run over under that
    seed. ``info["dynamics_family"]`` names the drawn family.

    Args:
        env_id: a pen task.
        seed: the run's seed.
        randomisation: the ranges.
        env_kwargs: further env kwargs of every episode.
    """

    def __init__(
        self,
        env_id: str,
        seed: int = 0,
        randomisation: Randomisation = DEFAULT_RANDOMISATION,
        env_kwargs: Mapping[str, Any] | None = None,
    ) -> None:
        self.env_id, self.randomisation = env_id, randomisation
        self.env_kwargs = dict(env_kwargs or {})
        self._run, self._episode = int(seed), 0
        self._env: gym.Env[Any, Any] = gym.make(env_id, **self.env_kwargs)
        self.observation_space = self._env.observation_space
        self.action_space = self._env.action_space
        self.family = "nominal"

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Draw the next episode's dynamics, make its env and reset it."""
        super().reset(seed=seed)
        if seed is not None:
            self._run, self._episode = int(seed), 0
        dynamics = episode_dynamics(self._run, self._episode, self.randomisation)
        self._episode += 1
        self._env.close()
        self._env = gym.make(self.env_id, **{**self.env_kwargs, **dynamics.env_kwargs})
        self.family = dynamics.family
        obs, info = self._env.reset(seed=dynamics.seed, options=options)
        return obs, {**info, "dynamics_family": self.family}

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Step the current episode's env."""
        return self._env.step(action)

    def close(self) -> None:
        """Close the current env."""
        self._env.close()


__all__ = [
    "DEFAULT_RANDOMISATION",
    "FAMILIES",
    "HELD_OUT_SEED_START",
    "NOMINAL",
    "OBSERVATION_NOISE",
    "SINGLE_FAMILIES",
    "EpisodeDynamics",
    "Randomisation",
    "RandomisedDynamicsEnv",
    "episode_dynamics",
]

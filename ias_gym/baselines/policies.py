"""The policy loader: a policy spec (a string of the command line) -> a policy object.

A policy is any object with Stable-Baselines3's ``predict(obs, state=None,
episode_start=None, deterministic=True) -> (action, state)`` (:class:`Policy`, defined with
the episode loop :func:`ias_gym.rollout.rollout` and re-exported here), as SB3's
``evaluate_policy`` takes: the rollout passes ``episode_start=True`` on the first step of
each episode, which resets a stateful one (the expert's controller).

:func:`load_policy` is the one place that dispatches on policy names: ``expert`` (the
grip-transform controller of the pen tasks, :class:`~ias_gym.baselines.expert.ExpertPolicy`),
``teleop`` (glove envs: zero action, the glove alone drives the hand, :class:`ZeroPolicy`),
``random`` (:class:`RandomPolicy`), or the path of a saved SB3 model (loaded without running
code from it, :mod:`ias_gym.safe_sb3`, :class:`ModelPolicy`). :func:`policy_source` says
what a recorded skill stores as its provenance.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from ias_gym.baselines.batch import batch_size
from ias_gym.errors import IasGymError, InputError, MissingDependencyError, PolicyNotFoundError  # noqa: F401 - defined there, raised here
from ias_gym.rollout import Policy  # re-exported: the protocol every episode loop calls
from ias_gym.safe_sb3 import LoadedPolicy, load_sb3_policy

#: Loads a policy for an env (the env's spaces, the expert's physics): e.g.
#: ``lambda env: load_policy("expert", env)``; for loops that build one env per setting.
PolicyFactory = Callable[[gym.Env[Any, Any]], Policy]


@dataclass
class ZeroPolicy:
    """The zero action every step (glove envs: the glove alone drives the hand).

    Args:
        space: the env's Box action space.
        observation_shape: the env's observation shape, to tell one observation from a
            batch ``(n, *shape)`` (``None``: always one).
    """

    space: gym.spaces.Box
    observation_shape: tuple[int, ...] | None = None

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """A fresh zero array of the space's shape and dtype, ``(n, ...)`` for a batch of n
        observations (SB3's signature)."""
        n = batch_size(observation, self.observation_shape)
        shape = self.space.shape if n is None else (n, *self.space.shape)
        return np.zeros(shape, dtype=self.space.dtype), state


class RandomPolicy:
    """Uniform random actions sampled from the env's action space.

    The space is seeded once, here: the episodes that follow draw one continuing stream
    (what ``ias-gym evaluate --policy random --seed S`` has always done).

    Args:
        space: the env's action space (seeded in place).
        seed: seed of the action sampling (``None``: unseeded).
        observation_shape: the env's observation shape, to tell one observation from a
            batch ``(n, *shape)`` (``None``: always one).
    """

    def __init__(
        self,
        space: gym.Space[Any],
        seed: int | None = None,
        observation_shape: tuple[int, ...] | None = None,
    ) -> None:
        self.space = space
        self.observation_shape = observation_shape
        space.seed(seed)

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[Any, Any]:
        """A sample of the action space, ``n`` stacked samples for a batch of n observations
        (SB3's signature; ``deterministic`` is ignored)."""
        n = batch_size(observation, self.observation_shape)
        if n is None:
            return self.space.sample(), state
        return np.stack([self.space.sample() for _ in range(n)]), state


@dataclass(frozen=True)
class ModelPolicy:
    """A saved SB3 model's policy (:func:`ias_gym.safe_sb3.load_sb3_policy`).

    Attributes:
        loaded: the loaded policy (its ``algorithm`` and the SB3 ``policy`` module).
    """

    loaded: LoadedPolicy

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """The SB3 policy's ``predict`` (its recurrent state passed through)."""
        action, state = self.loaded.policy.predict(
            observation, state=state, episode_start=episode_start, deterministic=deterministic
        )
        return np.asarray(action), state


#: The policy names :func:`load_policy` knows (anything else is a model file's path).
EXPERT = "expert"
RANDOM = "random"


#: Policy spec of glove envs: zero action, the glove alone drives the hand.
TELEOP = "teleop"

#: Policy spec of the model shipped for the env (``ias_gym/assets/policies/<env id>.zip``).
SHIPPED = "shipped"


def shipped_policy_path(env_id: str) -> Path:
    """The SB3 model shipped for ``env_id`` (its model card: ``assets/policies/README.md``).

    Raises:
        PolicyNotFoundError: no model is shipped for ``env_id``.
    """
    from importlib.resources import files

    folder = Path(str(files("ias_gym") / "assets" / "policies"))
    path = folder / f"{env_id}.zip"
    if not path.is_file():
        shipped = sorted(p.stem for p in folder.glob("*.zip"))
        raise PolicyNotFoundError(
            f"no policy is shipped for {env_id}; shipped: {', '.join(shipped) or 'none'} "
            "(train one: docs/results-learning.md)"
        )
    return path


def load_policy(
    spec: str, env: gym.Env[Any, Any], seed: int | None = None, *, trust_pickle: bool = False
) -> Policy:
    """The policy object (:class:`Policy`) for ``expert`` (pen tasks), ``teleop`` (glove envs:
    zero action, pure teleoperation), ``random``, ``shipped`` (the model shipped for the env,
    :func:`shipped_policy_path`) or a saved SB3 model's path.

    A model file is loaded without running code from it (:func:`ias_gym.safe_sb3.
    load_sb3_policy`), and must have been saved for ``env``'s spaces.

    Args:
        spec: ``"expert"``, ``"teleop"``, ``"random"``, ``"shipped"`` or the path of an SB3
            ``.zip``.
        env: the env the policy acts in.
        seed: seeds the ``random`` policy's action sampling.
        trust_pickle: load a model with SB3's own ``load``, which unpickles the file (runs
            code from it): only for files you trust.

    Raises:
        InputError: ``teleop`` on an env without a glove (or without a Box action space),
            or ``expert`` on a glove env (it has none: the person wearing the glove is the
            demonstrator).
        PolicyNotFoundError: ``spec`` is neither a known name nor an existing file, or
            ``shipped`` for an env without a shipped model.
        PolicyFileError: the file is not a usable model for ``env``;
            :class:`~ias_gym.safe_sb3.UntrustedPickleError` if it needs unpickling.
        MissingDependencyError: a model path was given but stable-baselines3 is not
            installed.
    """
    # The expert and the envs load MuJoCo models: imported when a policy is loaded, so that
    # importing this module (and the skill database above it) stays light.
    from ias_gym.baselines.expert import ExpertPolicy
    from ias_gym.envs.glove_grasp import GloveGraspEnv

    glove = isinstance(env.unwrapped, GloveGraspEnv)
    name = env.spec.id if env.spec is not None else type(env.unwrapped).__name__
    if spec == TELEOP:
        if not glove:
            raise InputError(
                f"policy {TELEOP!r} (zero action: the glove drives the hand) needs a glove "
                f"env such as IAS-GloveGrasp-v0, not {name}; use expert, random or a model"
            )
        space = env.action_space
        if not isinstance(space, gym.spaces.Box):
            raise InputError(f"{TELEOP!r} needs a Box action space, got {space}")
        return ZeroPolicy(space, _observation_shape(env))
    if spec == EXPERT:
        if glove:
            raise InputError(
                f"{name} has no expert: a glove session is demonstrated by the person wearing "
                f"the glove; use --policy {TELEOP} (zero action, pure teleoperation), random, "
                "or a saved SB3 model acting on top of the glove"
            )
        return ExpertPolicy(env)
    if spec == RANDOM:
        return RandomPolicy(env.action_space, seed, _observation_shape(env))
    path = shipped_policy_path(name) if spec == SHIPPED else Path(spec)
    if not path.is_file():
        raise PolicyNotFoundError(
            f"policy {spec!r} is not 'expert', 'teleop', 'random', 'shipped' or an existing SB3 "
            "model file"
        )
    try:  # optional heavy dependency (the [train] extra): only for a model file
        import stable_baselines3  # noqa: F401
    except ImportError:
        raise MissingDependencyError(
            "loading a saved model needs stable-baselines3: pip install 'ias-gym[train]'"
        ) from None
    return ModelPolicy(load_sb3_policy(path, env, trust_pickle=trust_pickle))


def _observation_shape(env: gym.Env[Any, Any]) -> tuple[int, ...] | None:
    shape = env.observation_space.shape
    return None if shape is None else tuple(shape)


def policy_source(policy_spec: str) -> str:
    """Provenance string of a policy spec: ``expert``, ``random``, ``teleop`` or
    ``policy:<abs path>`` (a glove session's is refined by
    :func:`~ias_gym.skills.record.record_episode`)."""
    if policy_spec in (EXPERT, RANDOM, TELEOP):
        return policy_spec
    return f"policy:{Path(policy_spec).resolve()}"

"""The policy loader: a policy spec (a string of the command line) -> ``obs -> action``.

The one place that dispatches on policy names: ``expert`` (the grip-transform controller
of the pen tasks, :class:`~ias_gym.baselines.expert.ExpertPolicy`), ``teleop`` (glove
envs: zero action, the glove alone drives the hand), ``random``, or the path of a saved
SB3 model (loaded without running code from it, :mod:`ias_gym.safe_sb3`).
:mod:`ias_gym.evaluation` and :mod:`ias_gym.skills.record` (layers above this one) take the
loaded callable; :func:`stateful` says when to load a fresh one per episode and
:func:`policy_source` what a recorded skill stores as its provenance.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from ias_gym.errors import IasGymError, InputError
from ias_gym.safe_sb3 import load_sb3_policy

#: A loaded policy: observation -> action.
Policy = Callable[[np.ndarray], np.ndarray]
#: The policy names :func:`load_policy` knows (anything else is a model file's path).
EXPERT = "expert"
RANDOM = "random"


class PolicyNotFoundError(InputError, FileNotFoundError):
    """A policy spec that is neither a known name nor an existing file."""


class MissingDependencyError(IasGymError, ImportError):
    """An optional dependency is not installed (the message says which extra to install)."""


#: Policy spec of glove envs: zero action, the glove alone drives the hand.
TELEOP = "teleop"


def load_policy(
    spec: str, env: gym.Env[Any, Any], seed: int | None = None, *, trust_pickle: bool = False
) -> Policy:
    """A callable ``obs -> action`` for ``expert`` (pen tasks), ``teleop`` (glove envs: zero
    action, pure teleoperation), ``random`` or a saved SB3 model's path.

    A model file is loaded without running code from it (:func:`ias_gym.safe_sb3.
    load_sb3_policy`), and must have been saved for ``env``'s spaces.

    Args:
        spec: ``"expert"``, ``"teleop"``, ``"random"`` or the path of an SB3 ``.zip``.
        env: the env the policy acts in.
        seed: seeds the ``random`` policy's action sampling.
        trust_pickle: load a model with SB3's own ``load``, which unpickles the file (runs
            code from it): only for files you trust.

    Raises:
        InputError: ``teleop`` on an env without a glove (or without a Box action space),
            or ``expert`` on a glove env (it has none: the person wearing the glove is the
            demonstrator).
        PolicyNotFoundError: ``spec`` is neither a known name nor an existing file.
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
        zero = np.zeros(space.shape, dtype=space.dtype)
        return lambda obs: zero.copy()
    if spec == EXPERT:
        if glove:
            raise InputError(
                f"{name} has no expert: a glove session is demonstrated by the person wearing "
                f"the glove; use --policy {TELEOP} (zero action, pure teleoperation), random, "
                "or a saved SB3 model acting on top of the glove"
            )
        expert = ExpertPolicy(env)
        return lambda obs: expert.predict(obs)[0]
    if spec == RANDOM:
        env.action_space.seed(seed)
        return lambda obs: env.action_space.sample()
    path = Path(spec)
    if not path.is_file():
        raise PolicyNotFoundError(
            f"policy {spec!r} is not 'expert', 'teleop', 'random' or an existing SB3 model file"
        )
    try:  # optional heavy dependency (the [train] extra): only for a model file
        import stable_baselines3  # noqa: F401
    except ImportError:
        raise MissingDependencyError(
            "loading a saved model needs stable-baselines3: pip install 'ias-gym[train]'"
        ) from None
    return load_sb3_policy(path, env, trust_pickle=trust_pickle)


def stateful(spec: str) -> bool:
    """Whether the policy ``spec`` keeps state across steps (the expert's controller), so
    that each episode needs a freshly loaded one.

    Args:
        spec: a policy spec as for :func:`load_policy`.
    """
    return spec == EXPERT


def policy_source(policy_spec: str) -> str:
    """Provenance string of a policy spec: ``expert``, ``random``, ``teleop`` or
    ``policy:<abs path>`` (a glove session's is refined by
    :func:`~ias_gym.skills.record.record_episode`)."""
    if policy_spec in (EXPERT, RANDOM, TELEOP):
        return policy_spec
    return f"policy:{Path(policy_spec).resolve()}"

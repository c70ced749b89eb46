"""A learned residual on top of the analytic assistant, trained with SB3's PPO.

:class:`ResidualAssistEnv` puts the impaired operator in the loop: every reset it builds an
``IAS-GloveAssist-v0`` session of a random person, skill and impairment (from the lists it
is given), runs the :class:`~ias_gym.assist.assistants.AnalyticAssistant` on it, and the
agent's action is a residual added to the analytic offsets, ``a = clip(a_analytic +
RESIDUAL_SCALE r)``. The observation is the env's (49) and the analytic action (10). The
reward restores the operator's intent: at every reset the same person, skill and seed is run
once unimpaired and unassisted (the simulator can; the reward is only needed in training),
and each step earns ``exp(-(|dp| / 3 mm)^2) + exp(-(|da| / 5 deg)^2)`` for the pen's centre
``p`` and axis ``a`` against that session's at the same step (the success test's tolerances,
:mod:`ias_gym.assist.sessions`), minus ``RESIDUAL_COST |r|^2``: the residual has to earn
its intervention. A dropped pen ends the episode, and with it the reward.
:class:`ResidualAssistant` acts with a saved model (loaded without unpickling,
:mod:`ias_gym.safe_sb3`) through the assistant protocol of :mod:`ias_gym.assist.sessions`.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from ias_gym.assist.assistants import AnalyticAssistant
from ias_gym.assist.sessions import (
    OBS_PEN,
    OBS_QUAT,
    POSITION_TOLERANCE,
    ROTATION_TOLERANCE,
    pen_axis,
    run_session,
)
from ias_gym.assist.skill_templates import SkillTemplate
from ias_gym.envs.glove_assist import OBS_SIZE
from ias_gym.glove.hand import N_JOINTS
from ias_gym.glove.impairments import Impairment, reference_kwargs
from ias_gym.glove.skills import SKILLS

FloatArray = NDArray[np.float64]

#: Size of a full residual relative to the action range [-].
RESIDUAL_SCALE = 0.1
#: Weight of the residual's squared size in the reward [-].
RESIDUAL_COST = 0.2


class ResidualAssistEnv(gym.Env[FloatArray, NDArray[np.float32]]):
    """Train a residual on the analytic assistant with the impaired operator in the loop.

    Args:
        templates: the library's templates (the analytic assistant's).
        persons: person ids drawn at every reset.
        impairments: impairment names drawn at every reset.
        skills: skills drawn at every reset.
        max_steps: steps per episode (the env's 400 = 4 s by default).
        operator: the simulated person: ``"closed_loop"`` or the open ``"script"``.
    """

    def __init__(
        self,
        templates: dict[str, SkillTemplate],
        persons: list[str],
        impairments: list[str],
        skills: tuple[str, ...] = SKILLS,
        max_steps: int = 400,
        operator: str = "closed_loop",
    ) -> None:
        self.templates = templates
        self.operator = operator
        self.persons, self.impairments, self.skills = persons, impairments, skills
        self.max_steps = max_steps
        self.observation_space = spaces.Box(
            -np.inf, np.inf, shape=(OBS_SIZE + N_JOINTS,), dtype=np.float64
        )
        self.action_space = spaces.Box(-1.0, 1.0, shape=(N_JOINTS,), dtype=np.float32)
        self.analytic = AnalyticAssistant(templates)
        self.env: Any = None
        self._base = np.zeros(N_JOINTS)
        self._steps = 0
        self._ref_pos = np.zeros((1, 3))
        self._ref_axis = np.zeros((1, 3))

    def _augment(self, obs: FloatArray) -> FloatArray:
        self._base = self.analytic.act(self.env.unwrapped)
        return np.concatenate([obs, self._base])

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[FloatArray, dict[str, Any]]:
        """A new session of a random person, skill and impairment."""
        super().reset(seed=seed)
        rng = self.np_random
        if self.env is not None:
            self.env.close()
        person, skill = str(rng.choice(self.persons)), str(rng.choice(list(self.skills)))
        impairment = Impairment.make(str(rng.choice(self.impairments)))
        self.env = gym.make(
            "IAS-GloveAssist-v0",
            person_id=person,
            skill=skill,
            impairment=impairment.name,
            operator=self.operator,
        )
        seed = int(rng.integers(2**31))
        reference = gym.make(
            "IAS-GloveAssist-v0",
            person_id=person,
            skill=skill,
            operator=self.operator,
            **reference_kwargs(impairment),
        )
        ref = run_session(reference, None, seed)
        reference.close()
        self._ref_pos, self._ref_axis = ref.pen_position, pen_axis(ref.pen_quat)
        obs, info = self.env.reset(seed=seed)
        self.analytic.reset(self.env.unwrapped)
        self._steps = 0
        return self._augment(obs), info

    def step(self, action: NDArray[Any]) -> tuple[FloatArray, float, bool, bool, dict[str, Any]]:
        """Apply the analytic offsets plus the residual."""
        r = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        total = np.clip(self._base + RESIDUAL_SCALE * r, -1.0, 1.0)
        obs, _, terminated, truncated, info = self.env.step(total)
        k = min(self._steps, len(self._ref_pos) - 1)  # the reference may have ended early
        self._steps += 1
        dp = float(np.linalg.norm(obs[OBS_PEN] - self._ref_pos[k]))
        da = float(np.linalg.norm(pen_axis(obs[None, OBS_QUAT])[0] - self._ref_axis[k]))
        reward = (
            math.exp(-((dp / POSITION_TOLERANCE) ** 2))
            + math.exp(-((da / ROTATION_TOLERANCE) ** 2))
            - RESIDUAL_COST * float(np.mean(r * r))
        )
        truncated = bool(truncated or self._steps >= self.max_steps)
        return self._augment(obs), reward, bool(terminated), truncated, info

    def close(self) -> None:
        """Close the session's env."""
        if self.env is not None:
            self.env.close()
            self.env = None


class ResidualAssistant:
    """The analytic assistant plus a trained residual, with the assistant protocol.

    Args:
        policy: ``obs (59,) -> residual (10,)`` (e.g. :class:`~ias_gym.safe_sb3.LoadedPolicy`).
        templates: the library's templates.
    """

    def __init__(self, policy: Any, templates: dict[str, SkillTemplate]) -> None:
        self.policy = policy
        self.analytic = AnalyticAssistant(templates)

    @classmethod
    def load(cls, path: str | Path, templates: dict[str, SkillTemplate]) -> ResidualAssistant:
        """A saved residual (``train/assist_residual.py``), loaded without unpickling.

        Raises:
            ~ias_gym.safe_sb3.PolicyFileError: not a residual assistant's model.
        """
        from ias_gym.safe_sb3 import load_sb3_policy

        env = ResidualAssistEnv(templates, ["p1"], ["none"])
        return cls(load_sb3_policy(path, env), templates)

    def reset(self, env: Any) -> None:
        """Start a session on ``env`` (unwrapped, just reset)."""
        self.analytic.reset(env)

    def posterior(self) -> dict[str, float]:
        """The analytic assistant's posterior."""
        return self.analytic.posterior()

    def act(self, env: Any) -> FloatArray:
        """The analytic offsets plus the residual, clipped to [-1, 1]."""
        base = self.analytic.act(env)
        obs = np.concatenate([env._observation(), base])
        r = np.clip(np.asarray(self.policy(obs), dtype=np.float64), -1.0, 1.0)
        out: FloatArray = np.clip(base + RESIDUAL_SCALE * r, -1.0, 1.0)
        return out

"""A learned residual on top of an assistant, trained with SB3's PPO.

:class:`ResidualAssistEnv` puts the impaired operator in the loop: every reset it builds an
``IAS-GloveAssist-v0`` session of a random person, skill and impairment spec (from the lists
it is given; ``sampled`` draws a family and its parameters from the env's random stream),
runs the base assistant on it, and the agent's action is a residual added to the base's
offsets, ``a = clip(a_base + RESIDUAL_SCALE r)``. Two bases (:data:`BASES`):

- ``"observation"``: the assistant on observations (:func:`~ias_gym.assist.policy.make_assistant`,
  the hardware path's): it and the residual read the observation alone;
- ``"analytic"``: the :class:`~ias_gym.assist.assistants.AnalyticAssistant`, which reads
  the env's state (a reference of what such help can do).

The agent's observation is the env's (49) and the base's action (10). The reward restores
the operator's intent: at every reset the same person, skill and seed is run once
unimpaired and unassisted (the simulator can; the reward is only needed in training, the
policy never reads it), and each step earns ``exp(-(|dp| / 3 mm)^2) + exp(-(|da| / 5
deg)^2)`` for the pen's centre ``p`` and axis ``a`` against that session's at the same step
(the success test's tolerances, :mod:`ias_gym.assist.sessions`), minus ``RESIDUAL_COST
|r|^2``: the residual has to earn its intervention. A dropped pen ends the episode, and with
it the reward. :class:`ResidualAssistant` (analytic base) and
:class:`ObservationResidualAssistant` (observation base) act with a saved model (loaded
without unpickling, :mod:`ias_gym.safe_sb3`) through the assistant protocols of
:mod:`ias_gym.assist.sessions`.
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
from ias_gym.assist.policy import ObservationAssistant, make_assistant
from ias_gym.assist.sessions import (
    OBS_PEN,
    OBS_QUAT,
    POSITION_TOLERANCE,
    ROTATION_TOLERANCE,
    pen_axis,
    run_session,
)
from ias_gym.assist.skill_templates import SkillTemplate
from ias_gym.envs.glove_assist import OBS_SIZE, OBSERVATION_PARTS
from ias_gym.envs.layout import observation_layout
from ias_gym.errors import InputError
from ias_gym.glove.hand import N_JOINTS
from ias_gym.glove.impairments import Impairment, reference_kwargs
from ias_gym.glove.skills import SKILLS

FloatArray = NDArray[np.float64]

#: Size of a full residual relative to the action range [-].
RESIDUAL_SCALE = 0.1
#: Weight of the residual's squared size in the reward [-].
RESIDUAL_COST = 0.2
#: The assistants a residual can sit on (module docstring).
BASES = ("observation", "analytic")
#: The model attribute that names a residual's base: ``train/assist_residual.py`` sets it
#: before saving, and SB3 stores it in the model's JSON ``data``.
BASE_ATTRIBUTE = "residual_base"


def check_base(path: str | Path, base: str) -> None:
    """Refuse a saved residual trained on another base than ``base`` (a model without the
    record is taken as the analytic base's, the older models').

    Raises:
        ~ias_gym.safe_sb3.PolicyFileError: trained on another base.
    """
    from ias_gym.safe_sb3 import PolicyFileError, read_model_json

    data = read_model_json(path)
    saved = data.get(BASE_ATTRIBUTE, "analytic")
    if saved != base:
        what = f"on the {saved!r} assistant" if BASE_ATTRIBUTE in data else "without a base"
        raise PolicyFileError(
            f"{path} is a residual {what}, not on the {base!r} one (train it with "
            f"train/assist_residual.py --base {base})"
        )


def _with_residual(base: FloatArray, r: FloatArray) -> FloatArray:
    """The action ``clip(base + RESIDUAL_SCALE r)`` of a base action and a residual in
    [-1, 1]: the one rule of training and acting."""
    out: FloatArray = np.clip(base + RESIDUAL_SCALE * r, -1.0, 1.0)
    return out


class _ObservationBase:
    """The assistant on observations as a residual's base."""

    def __init__(self, db: str | Path | None) -> None:
        self.assistant = make_assistant(db, layout=observation_layout(OBSERVATION_PARTS))

    def reset(self, env: Any) -> None:
        self.assistant.reset()

    def act(self, env: Any, obs: FloatArray) -> FloatArray:
        return self.assistant.act(obs)


class _AnalyticBase:
    """The analytic assistant (it reads the env's state) as a residual's base."""

    def __init__(self, templates: dict[str, SkillTemplate]) -> None:
        self.assistant = AnalyticAssistant(templates)

    def reset(self, env: Any) -> None:
        self.assistant.reset(env)

    def act(self, env: Any, obs: FloatArray) -> FloatArray:
        return self.assistant.act(env)


class ResidualAssistEnv(gym.Env[FloatArray, NDArray[np.float32]]):
    """Train a residual on an assistant with the impaired operator in the loop.

    Args:
        templates: the library's templates (the analytic base's; unused by the other).
        persons: person ids drawn at every reset.
        impairments: impairment specs drawn at every reset (``sampled`` included).
        skills: skills drawn at every reset.
        max_steps: steps per episode (the env's 400 = 4 s by default).
        operator: the simulated person: ``"closed_loop"`` or the open ``"script"``.
        base: the assistant under the residual, one of :data:`BASES`.
        db: the skill library of the observation base (None: the shipped one).

    Raises:
        InputError: an unknown base or impairment spec, or no person.
    """

    def __init__(
        self,
        templates: dict[str, SkillTemplate],
        persons: list[str],
        impairments: list[str],
        skills: tuple[str, ...] = SKILLS,
        max_steps: int = 400,
        operator: str = "closed_loop",
        base: str = "analytic",
        db: str | Path | None = None,
    ) -> None:
        if base not in BASES:
            raise InputError(f"residual base {base!r} is not known; choose one of {BASES}")
        if not persons:
            raise InputError("give at least one person to train the residual on")
        for spec in impairments:
            Impairment.make(spec)  # an unknown spec fails here, not at the first reset
        self.templates = templates
        self.operator = operator
        self.persons, self.impairments, self.skills = persons, impairments, skills
        self.max_steps = max_steps
        self.observation_space = spaces.Box(
            -np.inf, np.inf, shape=(OBS_SIZE + N_JOINTS,), dtype=np.float64
        )
        self.action_space = spaces.Box(-1.0, 1.0, shape=(N_JOINTS,), dtype=np.float32)
        self.assistant: _ObservationBase | _AnalyticBase = (
            _ObservationBase(db) if base == "observation" else _AnalyticBase(templates)
        )
        self.env: Any = None
        self._base = np.zeros(N_JOINTS)
        self._steps = 0
        self._ref_pos = np.zeros((1, 3))
        self._ref_axis = np.zeros((1, 3))

    def _augment(self, obs: FloatArray) -> FloatArray:
        self._base = self.assistant.act(self.env.unwrapped, obs)
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
        impairment = Impairment.make(str(rng.choice(self.impairments))).draw(rng)
        self.env = gym.make(
            "IAS-GloveAssist-v0",
            person_id=person,
            skill=skill,
            impairment=impairment.spec,
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
        self.assistant.reset(self.env.unwrapped)
        self._steps = 0
        return self._augment(obs), info

    def step(self, action: NDArray[Any]) -> tuple[FloatArray, float, bool, bool, dict[str, Any]]:
        """Apply the base's offsets plus the residual."""
        r = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        obs, _, terminated, truncated, info = self.env.step(_with_residual(self._base, r))
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


def _residual(policy: Any, obs: FloatArray, base: FloatArray) -> FloatArray:
    """``clip(base + RESIDUAL_SCALE policy([obs, base]))``, the policy's output clipped."""
    r = np.clip(np.asarray(policy(np.concatenate([obs, base])), dtype=np.float64), -1.0, 1.0)
    return _with_residual(base, r)


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
        """A saved residual (``train/assist_residual.py --base analytic``), loaded without
        unpickling.

        Raises:
            ~ias_gym.safe_sb3.PolicyFileError: not a residual assistant's model, or one on
                the assistant on observations.
        """
        from ias_gym.safe_sb3 import load_sb3_policy

        check_base(path, "analytic")
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
        return _residual(self.policy, env._observation(), self.analytic.act(env))


class ObservationResidualAssistant:
    """The assistant on observations plus a trained residual: it reads the observation
    alone, like its base (:class:`~ias_gym.assist.policy.ObservationAssistant`).

    Args:
        policy: ``[obs (49,), base action (10,)] -> residual (10,)``.
        assistant: the base, an :class:`~ias_gym.assist.policy.ObservationAssistant` on the
            env's layout.
    """

    #: It acts on the observation (:class:`~ias_gym.assist.sessions.AssistantPolicy`).
    reads_observations = True

    def __init__(self, policy: Any, assistant: ObservationAssistant) -> None:
        self.policy = policy
        self.assistant = assistant

    @classmethod
    def load(cls, path: str | Path, db: str | Path | None = None) -> ObservationResidualAssistant:
        """A saved residual (``train/assist_residual.py --base observation``) on the
        assistant of library ``db`` (None: the shipped one), loaded without unpickling.

        Raises:
            ~ias_gym.safe_sb3.PolicyFileError: not a residual assistant's model, or one on
                the analytic assistant.
        """
        from ias_gym.safe_sb3 import load_sb3_policy

        check_base(path, "observation")
        env = ResidualAssistEnv({}, ["p1"], ["none"], base="observation", db=db)
        base = env.assistant
        assert isinstance(base, _ObservationBase)
        return cls(load_sb3_policy(path, env), base.assistant)

    def reset(self) -> None:
        """Start a session."""
        self.assistant.reset()

    def posterior(self) -> dict[str, float]:
        """The base's posterior."""
        return self.assistant.posterior()

    def act(self, obs: Any) -> FloatArray:
        """The base's offsets plus the residual, clipped to [-1, 1].

        Raises:
            InputError: an observation of another env than ``IAS-GloveAssist-v0`` (the
                residual was trained on its 49 values; the base alone runs on others).
        """
        obs = np.asarray(obs, dtype=np.float64)
        if obs.shape != (OBS_SIZE,):
            raise InputError(
                f"the residual reads IAS-GloveAssist-v0's observation ({OBS_SIZE} values), not "
                f"{obs.shape}; on another env use its base (make_assistant) alone"
            )
        return _residual(self.policy, obs, self.assistant.act(obs))

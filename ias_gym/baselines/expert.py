"""The grip-transform controller as an expert policy with Stable-Baselines3's interface."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from ias_gym.baselines.grip_transform_control import ControllerGains, GripTransformController
from ias_gym.envs.pen_hand_env import FloatArray, PenHandEnv


class ExpertPolicy:
    """``predict(obs) -> (action, None)`` from the grip-transform controller.

    The expert is privileged: it ignores the observation and reads the unwrapped env's
    simulation state (contacts, Jacobians, the task's reference) through ``env.physics`` and
    ``env.reference()``; it acts only through the env's action (normalised torques). Use it
    with the env it was built for, stepping that env with the returned actions.

    Args:
        env: an ``IAS-Pen*`` environment (wrappers are looked through).
        gains: controller gains (defaults tuned for the 10 ms control period).
    """

    def __init__(self, env: gym.Env[Any, Any], gains: ControllerGains | None = None) -> None:
        unwrapped = env.unwrapped
        if not isinstance(unwrapped, PenHandEnv):
            raise TypeError(
                f"the expert controls IAS pen environments, got {type(unwrapped).__name__}"
            )
        self.env = unwrapped
        self.gains = gains or ControllerGains()
        self.reset()

    def reset(self) -> None:
        """Forget the controller's memory (last feasible forces); call at episode start."""
        self.controller = GripTransformController(
            f0=self.env.config.min_grasp_force, gains=self.gains
        )

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[FloatArray, None]:
        """The action for the env's current state (SB3's signature; ``observation`` unused)."""
        if episode_start is not None and bool(np.any(episode_start)):
            self.reset()
        return self.controller.action(self.env).astype(np.float32), None

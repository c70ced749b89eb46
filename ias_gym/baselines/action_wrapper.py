"""``GripTransformAction``: the agent commands the object, the grip transform moves the fingers."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ias_gym.baselines.gains import ControllerGains
from ias_gym.baselines.grip_transform_control import GripTransformController
from ias_gym.envs.pen_hand_env import FloatArray, PenHandEnv


class GripTransformAction(gym.ActionWrapper[FloatArray, Any, Any]):
    """Object-level actions turned into joint torques by the control law of Theorem 1.

    The action, ``Box(-1, 1, (3k,))`` for a hand of k fingers (``(12,)`` on the four-finger
    hand), is a normalised offset of what the expert commands:

    - ``action[0:3] * linear_accel_scale``: added to the desired linear acceleration of the
      pen [m/s^2] (eq. 41's ``r''_d``),
    - ``action[3:6] * angular_accel_scale``: added to its desired angular acceleration
      [rad/s^2],
    - ``action[6:] * internal_force_scale``: added to the internal forces f_int of the
      reference [N], i.e. ``c_h^d += N offset`` (eq. 7; 3k - 6 of them).

    A zero action reproduces the expert (:class:`~ias_gym.baselines.expert.ExpertPolicy`)
    exactly. ``info`` gains ``"internal_force_infeasible"``: how many control steps of the
    episode had no feasible internal-force solution (the last feasible one was used).

    Args:
        env: an ``IAS-Pen*`` environment.
        linear_accel_scale: [m/s^2] per unit action.
        angular_accel_scale: [rad/s^2] per unit action.
        internal_force_scale: [N] per unit action.
        gains: controller gains.
    """

    def __init__(
        self,
        env: gym.Env[FloatArray, Any],
        linear_accel_scale: float = 1.0,
        angular_accel_scale: float = 20.0,
        internal_force_scale: float = 0.1,
        gains: ControllerGains | None = None,
    ) -> None:
        super().__init__(env)
        if not isinstance(env.unwrapped, PenHandEnv):
            raise TypeError(
                f"GripTransformAction wraps IAS pen environments, got {type(env.unwrapped)}"
            )
        self.pen_env: PenHandEnv = env.unwrapped
        self.gains = gains or ControllerGains()
        self._scale = np.concatenate(
            [
                np.full(3, linear_accel_scale),
                np.full(3, angular_accel_scale),
                np.full(3 * self.pen_env.physics.n_fingers - 6, internal_force_scale),
            ]
        )
        self.action_space = spaces.Box(-1.0, 1.0, shape=self._scale.shape, dtype=np.float32)
        self._new_controller()

    def _new_controller(self) -> None:
        self.controller = GripTransformController(
            f0=self.pen_env.config.min_grasp_force, gains=self.gains
        )

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[FloatArray, dict[str, Any]]:
        """Reset the env and the controller's memory."""
        obs, info = self.env.reset(seed=seed, options=options)
        self._new_controller()
        info["internal_force_infeasible"] = 0
        return obs, info

    def action(self, action: Any) -> FloatArray:
        """Joint torques (the env's normalised action) for an object-level action.

        Raises:
            ValueError: wrong shape, NaN or inf.
        """
        a = np.asarray(action, dtype=float)
        if a.shape != self._scale.shape:
            raise ValueError(f"action must have shape {self._scale.shape}, got {a.shape}")
        if not np.isfinite(a).all():
            raise ValueError(f"action contains NaN or inf: {a}; actions must be finite")
        offset = np.clip(a, -1.0, 1.0) * self._scale
        # float32 like the env's action space (and the expert's predict): bit-identical.
        return self.controller.action(self.pen_env, offset[:6], offset[6:]).astype(np.float32)

    def step(self, action: Any) -> tuple[FloatArray, float, bool, bool, dict[str, Any]]:
        """Step with an object-level action; adds the infeasible-step count to ``info``."""
        obs, reward, terminated, truncated, info = self.env.step(self.action(action))
        info["internal_force_infeasible"] = self.controller.infeasible_count
        return obs, float(reward), terminated, truncated, info

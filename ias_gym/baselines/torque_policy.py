"""What the transfer baselines share: a policy that computes joint torques from the env's
state and acts through the env's normalised action, and the rotation that carries points
fixed on the object along the reference's axis.

:class:`~ias_gym.baselines.kinematic.KinematicPolicy` and
:class:`~ias_gym.baselines.retarget.RetargetPolicy` subclass :class:`TorquePolicy`: each
defines :meth:`TorquePolicy.torques` and :meth:`TorquePolicy.reset`; SB3's ``predict`` is
here once.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from ias_gym.envs.pen_hand_env import FloatArray, PenHandEnv


def rotation_between(a: FloatArray, b: FloatArray) -> FloatArray:
    """The smallest rotation matrix taking unit vector ``a`` to unit vector ``b`` (Rodrigues)."""
    v = np.cross(a, b)
    c = float(a @ b)
    if c < -1.0 + 1e-12:  # opposite: any half turn about an axis across a
        raise ValueError("the reference axis turned by 180 degrees")
    vx = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    result: FloatArray = np.eye(3) + vx + vx @ vx / (1.0 + c)
    return result


def side_shares(normals: FloatArray) -> FloatArray:
    """Each finger's share of its side's press, ``(k / 2) / (fingers on its side)``, ``(k,)``.

    The sides are above and below the pen (the sign of the contact normal's vertical part,
    paper frame: y up). The same total press from above and below, split among the fingers
    of each side: equal presses on a hand with more fingers on one side push the object off
    (measured on the three-finger hand with the kinematic squeeze: every skill dropped).

    Args:
        normals: ``(k, 3)`` the contacts' normals into the pen.
    """
    sides = np.sign(normals[:, 1])
    count = np.where(sides > 0, np.sum(sides > 0), np.sum(sides <= 0))
    result: FloatArray = (len(sides) / 2) / count
    return result


class TorquePolicy:
    """``predict(obs) -> (action, None)`` from :meth:`torques`, the env's torques [N m]
    normalised by its motors' ranges and clipped to [-1, 1].

    Privileged like the expert (:class:`~ias_gym.baselines.expert.ExpertPolicy`): a subclass
    reads the unwrapped env's reference and physics, and acts only through the env's action.

    Args:
        env: an ``IAS-Pen*`` environment with a ``reference()`` (wrappers are looked through).
        what: the baseline's name, for the error on another env.

    Raises:
        TypeError: ``env`` is not an IAS pen environment.
    """

    def __init__(self, env: gym.Env[Any, Any], what: str) -> None:
        unwrapped = env.unwrapped
        if not isinstance(unwrapped, PenHandEnv):
            raise TypeError(
                f"the {what} controls IAS pen environments, got {type(unwrapped).__name__}"
            )
        self.env = unwrapped

    def reset(self) -> None:
        """Forget what the last episode left (called on SB3's ``episode_start``)."""
        raise NotImplementedError

    def torques(self) -> FloatArray:
        """Joint torques [N m] for the env's current state and reference."""
        raise NotImplementedError

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
        action = np.clip(self.torques() / self.env._ctrl_max, -1.0, 1.0)
        return action.astype(np.float32), None

"""The paper's control law (Theorem 1, eq. 45) as controller, expert policy and action wrapper."""

from ias_gym.baselines.action_wrapper import GripTransformAction
from ias_gym.baselines.expert import ExpertPolicy
from ias_gym.baselines.grip_transform_control import ControllerGains, GripTransformController

__all__ = ["ControllerGains", "ExpertPolicy", "GripTransformAction", "GripTransformController"]

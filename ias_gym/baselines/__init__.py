"""The paper's control law (Theorem 1, eq. 45) and the policies built on it.

This package spans two layers (see docs/layout.md), so its ``__init__``
imports nothing: ``import ias_gym.baselines.law`` must not drag the envs in.

- :mod:`~ias_gym.baselines.law`: the law as pure functions (numpy only);
- :mod:`~ias_gym.baselines.grip_transform_control`: :class:`GripTransformController`,
  :class:`ControllerGains` (the law on a pen env);
- :mod:`~ias_gym.baselines.expert`: :class:`ExpertPolicy` (SB3 ``predict`` interface, one env
  or a vector env), :class:`BatchedExpert`, :class:`ExpertActionWrapper` (worker processes);
- :mod:`~ias_gym.baselines.action_wrapper`: :class:`GripTransformAction`;
- :mod:`~ias_gym.baselines.batch`: SB3's batch convention of ``predict``;
- :mod:`~ias_gym.baselines.policies`: the policy loader (``expert``, ``teleop``,
  ``random``, a saved model).
"""

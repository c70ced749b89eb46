"""Assisting the glove operator (issue #14, paper Flow 3): recognise the intended skill and
complete it from the skill library.

- :mod:`~ias_gym.assist.impairments`: impaired operators (tremor, weak grip, lag, biased
  calibration, small hand).
- :mod:`~ias_gym.assist.env`: ``IAS-GloveAssist-v0``, the glove world with an impaired operator.
- :mod:`~ias_gym.assist.assistants`: the analytic assistant (template + grasp margin).
- :mod:`~ias_gym.assist.evaluation`: sessions with and without an assistant, success against
  the unimpaired operator, intervention size, intent-switch latency.
"""

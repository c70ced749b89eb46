"""Assisting the glove's wearer (paper Flow 3): intent recognition, on-line
acquisition, and completing the recognised skill from the skill library.

- :mod:`~ias_gym.assist.stream`, :mod:`~ias_gym.assist.recognition`,
  :mod:`~ias_gym.assist.metrics`: what the recogniser sees, the recognisers, their metrics.
- :mod:`~ias_gym.assist.assistants`: the analytic assistant (template + grasp margin).
- :mod:`~ias_gym.assist.sessions`: sessions with and without an assistant, success against
  the unimpaired operator, intervention size, intent-switch latency.

The impaired operators (:mod:`ias_gym.glove.impairments`, their specs in
:mod:`ias_gym.glove.impairment_spec`) and ``IAS-GloveAssist-v0``, the glove world with an
impaired operator (:mod:`ias_gym.envs.glove_assist`), live below this package, with the glove
and the other envs.
"""

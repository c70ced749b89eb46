"""Assisting the glove's wearer (paper Flow 3): intent recognition, on-line
acquisition, and completing the recognised skill from the skill library.

- :mod:`~ias_gym.assist.stream`, :mod:`~ias_gym.assist.recognition_features`: what the
  recogniser sees; :mod:`~ias_gym.assist.recognition` (the protocol, posterior and unknown
  detection), :mod:`~ias_gym.assist.dtw_recogniser`, :mod:`~ias_gym.assist.phase_recogniser`,
  :mod:`~ias_gym.assist.recogniser_registry`: the recognisers;
  :mod:`~ias_gym.assist.metrics`: their metrics.
- :mod:`~ias_gym.assist.assistants`: the analytic assistant (template + grasp margin).
- :mod:`~ias_gym.assist.policy`, :mod:`~ias_gym.assist.skill_motions`: the assistant on
  observations and the library's skill motions it completes.
- :mod:`~ias_gym.assist.sessions`: sessions with and without an assistant, success against
  the unimpaired operator, intervention size, intent-switch latency;
  :mod:`~ias_gym.assist.assistance_evaluation`: an assistant judged over persons and
  impairments against the unimpaired reference sessions.

The impaired operators (:mod:`ias_gym.glove.impairments`, their specs in
:mod:`ias_gym.glove.impairment_spec`) and ``IAS-GloveAssist-v0``, the glove world with an
impaired operator (:mod:`ias_gym.envs.glove_assist`), live below this package, with the glove
and the other envs.
"""

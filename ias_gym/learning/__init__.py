"""Learning from the skill database: behaviour cloning into Stable-Baselines3, then PPO.

The top library layer (above skills and evaluation), the ``[train]`` extra: its modules
import torch and stable-baselines3 at module level, so ``import ias_gym`` never imports
this package; import the modules themselves (this file imports none of them).

The learner is an ordinary SB3 ``PPO("MlpPolicy", ...)`` model, so that a cloned policy
saves, loads (``ias-gym evaluate --policy FILE.zip``) and fine-tunes with PPO like any
other. What the pen tasks need (measured on 50 held-out seeds; ``train/`` has the
commands), one module each:

- :mod:`ias_gym.learning.dart`: **demonstrations with noise injection** (DART, Laskey et
  al. 2017). Cloned from clean expert episodes, a policy leaves the narrow band of states
  the expert visits and drops the pen (0 % success); recorded with small noise on the
  expert's torques and labelled with its clean actions, 88-100 %.
- :mod:`ias_gym.learning.demonstrations`: (observation, action, return) triples read from
  the skill database.
- :mod:`ias_gym.learning.normalisation`: **observation normalisation inside the policy**
  (:class:`~ias_gym.learning.normalisation.ObservationNormalizer`, which the saved model
  carries: no ``VecNormalize`` file).
- :mod:`ias_gym.learning.cloning`: **enough optimisation** of the actor (100 epochs over
  ~20k pairs: 100 %; 30 epochs: 2 %) and an exploration noise the task tolerates.
- :mod:`ias_gym.learning.finetune`: PPO with tiny steps, the actor frozen while the critic
  warms up, the best policy on validation seeds kept; SB3 training envs and callbacks.
- :mod:`ias_gym.learning.dagger`: **DAgger** with the analytic expert as teacher under
  randomised dynamics (:mod:`~ias_gym.learning.expert_labelling`,
  :mod:`~ias_gym.learning.randomised_dynamics`): labels only where the expert's grasp model
  held, clones fitted by Huber's loss.
- :mod:`ias_gym.learning.ensemble`: **ensembles of clones** as one SB3 model (the mean
  action of K clones, exactly), which make a clone's robustness less a matter of its seed.
- :mod:`ias_gym.learning.demo_rl`: **SAC with demonstrations** in its replay buffer (RLPD's
  symmetric sampling), a pretrained actor and TD3+BC's cloning term.
- :mod:`ias_gym.learning.offline`: offline RL on Minari datasets with d3rlpy (BC, IQL, CQL;
  the ``[offline]`` extra) beside the cloning above, on the same data.
"""

# Checked once here, before any module of the package loads, for one clear message instead
# of a bare "No module named 'torch'" from whichever module comes first.
try:
    import stable_baselines3  # noqa: F401
    import torch  # noqa: F401
except ImportError as exc:  # pragma: no cover - depends on the installed extras
    raise ImportError(
        "ias_gym.learning needs torch and stable-baselines3: pip install 'ias-gym[train]'"
    ) from exc

"""Where work runs: worker processes, the batched vector envs and the per-seed job runner.

- :mod:`~ias_gym.runtime.jobs`: :class:`~ias_gym.runtime.jobs.Backend` (serial, a process
  pool, or Ray) and :func:`~ias_gym.runtime.jobs.run_jobs`, which maps a job over items
  (seeds) with results in order, and retries a job whose worker died.
- :mod:`~ias_gym.runtime.workers`: :class:`~ias_gym.runtime.workers.BatchedWorkers`, the
  processes that each step a batch of envs through shared memory.
- :mod:`~ias_gym.runtime.vector_env`: Gymnasium's ``VectorEnv`` on those workers
  (:func:`~ias_gym.runtime.vector_env.make_batched_vec`, also ``ias_gym.make_batched_vec``).
- :mod:`~ias_gym.runtime.sb3_vec_env`: SB3's ``VecEnv`` on them (needs the ``[train]``
  extra; this package's import does not load it).

A worker that dies, hangs or cannot start is one error, :class:`~ias_gym.errors.WorkerError`.
The package imports only gymnasium, numpy and :mod:`ias_gym.errors`: nothing of the envs.
"""

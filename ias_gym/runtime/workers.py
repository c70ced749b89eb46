"""The worker processes behind the batched vector envs: each steps a batch of envs.

:class:`BatchedWorkers` starts ``num_workers`` processes, gives each a contiguous batch of
the env functions, and moves observations, actions, rewards and the termination flags
through shared memory; a batch step is one small pipe message per worker (the command out,
the envs' ``info`` dicts back). A worker that dies, times out or cannot build its envs is a
:class:`~ias_gym.errors.WorkerError`. The Gymnasium adapter is
:mod:`ias_gym.runtime.vector_env`, the SB3 one :mod:`ias_gym.runtime.sb3_vec_env`.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import traceback
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection, wait
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import (
    batch_space,
    create_shared_memory,
    iterate,
    read_from_shared_memory,
    write_to_shared_memory,
)
from numpy.typing import NDArray

from ias_gym.errors import InputError, WorkerError

EnvFn = Callable[[], gym.Env[Any, Any]]
#: One env's step result in a worker's reply: (``{"final_obs", "final_info"}`` of an episode
#: that ended this step in same-step mode, else None; the env's info).
StepInfo = tuple[dict[str, Any] | None, dict[str, Any]]


class BatchedWorkers:
    """``len(env_fns)`` envs in ``num_workers`` processes, each stepping a contiguous batch.

    The pool behind :class:`~ias_gym.runtime.vector_env.BatchedVectorEnv` (Gymnasium) and
    :class:`~ias_gym.runtime.sb3_vec_env.BatchedVecEnv` (SB3): it moves observations, actions,
    rewards and flags through shared memory and returns the envs' ``info`` dicts as lists.

    Args:
        env_fns: one function per env that builds it (run in the worker; pickled with
            cloudpickle, so closures work). ``env_fns[0]`` is also called once here, for the
            spaces and metadata.
        num_workers: worker processes (default: ``min(len(env_fns), os.cpu_count())``); env
            ``i`` runs in worker ``i * num_workers // len(env_fns)``-ish (contiguous
            batches whose sizes differ by at most one).
        context: multiprocessing start method (``"fork"``, ``"forkserver"``, ``"spawn"``;
            default: the platform's).
        autoreset_mode: Gymnasium's autoreset convention (:class:`AutoresetMode` or its value).
        timeout: longest wait for a worker's reply [s] (``None``: no limit; a worker that
            dies is noticed at once either way).

    Raises:
        InputError: no envs, or ``num_workers`` outside ``1..len(env_fns)``.
        WorkerError: a worker could not build its envs (the message has its traceback).
    """

    def __init__(
        self,
        env_fns: Sequence[EnvFn],
        num_workers: int | None = None,
        *,
        context: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        timeout: float | None = None,
    ) -> None:
        n = len(env_fns)
        if n < 1:
            raise InputError("env_fns is empty: give at least one env function")
        if num_workers is None:
            num_workers = min(n, os.cpu_count() or 1)
        if not 1 <= num_workers <= n:
            raise InputError(
                f"num_workers={num_workers} must be between 1 and the number of envs ({n})"
            )
        self.num_envs = n
        self.num_workers = num_workers
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        self.timeout = timeout
        self.closed = False
        self._broken = ""
        self._conns: list[Connection] = []
        self._procs: list[Any] = []

        dummy = env_fns[0]()
        self.single_observation_space: gym.Space[Any] = dummy.observation_space
        self.single_action_space: gym.Space[Any] = dummy.action_space
        self.metadata: dict[str, Any] = dict(dummy.metadata)
        self.render_mode: str | None = dummy.render_mode
        self.spec = dummy.spec
        dummy.close()
        del dummy

        ctx: Any = mp.get_context(context)
        self._obs_shm = create_shared_memory(self.single_observation_space, n, ctx)
        self._act_shm = create_shared_memory(self.single_action_space, n, ctx)
        self._rew_shm = ctx.RawArray("d", n)
        self._flag_shm = ctx.RawArray("b", 2 * n)  # terminated, truncated
        self.observations: Any = read_from_shared_memory(
            self.single_observation_space, self._obs_shm, n
        )
        self._actions: Any = read_from_shared_memory(self.single_action_space, self._act_shm, n)
        self.rewards: NDArray[np.float64] = np.frombuffer(self._rew_shm, dtype=np.float64)
        flags = np.frombuffer(self._flag_shm, dtype=np.bool_).reshape(2, n)
        self.terminations: NDArray[np.bool_] = flags[0]
        self.truncations: NDArray[np.bool_] = flags[1]
        self.batched_action_space = batch_space(self.single_action_space, n)

        sizes = [n // num_workers + (k < n % num_workers) for k in range(num_workers)]
        self.bounds = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
        try:
            for k in range(num_workers):
                lo, hi = int(self.bounds[k]), int(self.bounds[k + 1])
                parent, child = ctx.Pipe()
                proc = ctx.Process(
                    target=_worker,
                    name=f"BatchedWorkers-{k}",
                    args=(
                        child,
                        parent,
                        _Pickled(list(env_fns[lo:hi])),
                        (lo, hi, n),
                        self.single_observation_space,
                        self.single_action_space,
                        (self._obs_shm, self._act_shm, self._rew_shm, self._flag_shm),
                        self.autoreset_mode.value,
                    ),
                    daemon=True,
                )
                proc.start()
                child.close()
                self._conns.append(parent)
                self._procs.append(proc)
            self._gather("start")
        except BaseException:
            self.close(terminate=True)
            raise

    def reset(
        self,
        seeds: Sequence[int | None],
        options: dict[str, Any] | Sequence[dict[str, Any] | None] | None = None,
        mask: NDArray[np.bool_] | None = None,
    ) -> list[dict[str, Any] | None]:
        """Reset the envs (those in ``mask`` only, if given): observations in shared memory.

        Args:
            seeds: one seed per env (``None``: do not reseed).
            options: passed to every env's ``reset``, or one per env.
            mask: ``(num_envs,)`` bool, the envs to reset (default: all).

        Returns:
            Each env's reset info (``None`` for an env not reset).
        """
        per_env = (
            [options] * self.num_envs if options is None or isinstance(options, dict) else options
        )
        for k, conn in enumerate(self._conns):
            lo, hi = self.bounds[k], self.bounds[k + 1]
            part = None if mask is None else mask[lo:hi].tolist()
            message = (list(seeds[lo:hi]), list(per_env[lo:hi]), part)
            self._send(k, conn, ("reset", message))
        return [info for infos in self._gather("reset") for info in infos]

    def write_actions(self, actions: Any) -> None:
        """Put a batch of actions (an element of the batched action space) in shared memory.

        Raises:
            ValueError: a Box action batch of the wrong shape.
        """
        if isinstance(self.single_action_space, spaces.Box):
            a = np.asarray(actions)
            shape = (self.num_envs, *self.single_action_space.shape)
            if a.shape != shape:
                raise ValueError(f"actions must have shape {shape}, got {a.shape}")
            self._actions[...] = a
        else:
            for i, a in enumerate(iterate(self.batched_action_space, actions)):
                write_to_shared_memory(self.single_action_space, i, a, self._act_shm)

    def step(self, actions: Any) -> list[StepInfo]:
        """Step every env with its action: results in shared memory, infos returned."""
        self.write_actions(actions)
        for k, conn in enumerate(self._conns):
            self._send(k, conn, ("step", None))
        return [info for infos in self._gather("step") for info in infos]

    def call(
        self,
        name: str,
        args: Sequence[Any] = (),
        kwargs: dict[str, Any] | None = None,
        indices: Sequence[int] | None = None,
    ) -> list[Any]:
        """Call method ``name`` of the envs (or read the attribute if it is not callable).

        The attribute is looked up through the wrappers (``env.get_wrapper_attr``).

        Args:
            name: attribute name.
            args, kwargs: the call's arguments.
            indices: the envs (default: all), in this order.

        Returns:
            One result per env of ``indices``.
        """
        return self._per_env("call", (name, tuple(args), dict(kwargs or {})), indices)

    def get_attr(self, name: str, indices: Sequence[int] | None = None) -> list[Any]:
        """Attribute ``name`` of the envs ``indices`` (default: all), through the wrappers."""
        return self._per_env("get_attr", name, indices)

    def set_attr(
        self, name: str, values: Sequence[Any], indices: Sequence[int] | None = None
    ) -> None:
        """Set attribute ``name`` of the envs ``indices`` (default: all) to one value each."""
        idx = list(range(self.num_envs)) if indices is None else list(indices)
        if len(values) != len(idx):
            raise InputError(f"set_attr({name!r}) needs {len(idx)} values, got {len(values)}")
        self._per_env("set_attr", name, idx, values=list(values))

    def is_wrapped(self, wrapper_class: type, indices: Sequence[int] | None = None) -> list[bool]:
        """Whether each env of ``indices`` (default: all) has a ``wrapper_class`` wrapper."""
        return [bool(r) for r in self._per_env("is_wrapped", wrapper_class, indices)]

    def close(self, terminate: bool = False, timeout: float = 5.0) -> None:
        """Close the envs and end the workers (terminated if they do not end in ``timeout``).

        Args:
            terminate: end the workers at once, without closing their envs.
            timeout: how long to wait for each worker to end [s].
        """
        if self.closed:
            return
        self.closed = True
        if not terminate and not self._broken:
            for conn in self._conns:
                with contextlib.suppress(OSError):
                    conn.send(("close", None))
            for k in range(len(self._conns)):
                with contextlib.suppress(Exception):
                    self._recv(k, "close", timeout)
        for proc in self._procs:
            proc.join(0 if terminate else timeout)
            if proc.is_alive():
                proc.terminate()
                proc.join(timeout)
        for conn in self._conns:
            conn.close()

    def __del__(self) -> None:
        if not getattr(self, "closed", True):
            self.close(terminate=True)

    # ------------------------------------------------------------------ plumbing
    def _per_env(
        self,
        cmd: str,
        data: Any,
        indices: Sequence[int] | None,
        values: list[Any] | None = None,
    ) -> list[Any]:
        """Send ``cmd`` for the envs ``indices`` to their workers; results in that order."""
        idx = list(range(self.num_envs)) if indices is None else [int(i) for i in indices]
        bad = [i for i in idx if not 0 <= i < self.num_envs]
        if bad:
            raise InputError(f"env indices {bad} are not in 0..{self.num_envs - 1}")
        owner = np.searchsorted(self.bounds, idx, side="right") - 1
        results: dict[int, Any] = {}
        busy = []
        for k, conn in enumerate(self._conns):
            mine = [j for j, w in enumerate(owner) if w == k]
            if not mine:
                continue
            local = [idx[j] - int(self.bounds[k]) for j in mine]
            vals = None if values is None else [values[j] for j in mine]
            self._send(k, conn, (cmd, (data, local, vals)))
            busy.append((k, mine))
        replies = self._gather(cmd, [k for k, _ in busy])
        for (_, mine), out in zip(busy, replies, strict=True):
            results.update(zip(mine, out, strict=True))
        return [results[j] for j in range(len(idx))]

    def _send(self, k: int, conn: Connection, message: tuple[str, Any]) -> None:
        if self.closed:
            raise WorkerError("the vector env is closed")
        if self._broken:
            raise WorkerError(self._broken)
        try:
            conn.send(message)
        except OSError as e:  # a broken pipe: the worker is gone
            self._fail(k, message[0], e)

    def _gather(self, cmd: str, workers: Sequence[int] | None = None) -> list[Any]:
        """Every worker's reply (all are read, so the pipes stay in step); raise the first
        error after that."""
        replies = [self._recv(k, cmd, self.timeout) for k in (workers or range(self.num_workers))]
        for ok, payload in replies:
            if not ok:
                raise _rebuild_error(payload)
        return [payload for _, payload in replies]

    def _recv(self, k: int, cmd: str, timeout: float | None) -> tuple[bool, Any]:
        conn, proc = self._conns[k], self._procs[k]
        # Waiting on the process's sentinel too: a worker that dies is noticed at once.
        ready = wait([conn, proc.sentinel], timeout)
        if conn in ready:
            try:
                reply: tuple[bool, Any] = conn.recv()
                return reply
            except (EOFError, OSError) as e:
                self._fail(k, cmd, e)
        if not ready:
            self._broken = f"worker {k} (pid {proc.pid}) did not answer {cmd!r} within {timeout} s"
            raise WorkerError(self._broken)
        self._fail(k, cmd, None)
        raise AssertionError("unreachable")  # pragma: no cover

    def _fail(self, k: int, cmd: str, cause: BaseException | None) -> None:
        proc = self._procs[k]
        proc.join(0.1)
        lo, hi = self.bounds[k], self.bounds[k + 1] - 1
        self._broken = (
            f"worker {k} (pid {proc.pid}, envs {lo}..{hi}) died during {cmd!r} "
            f"(exit code {proc.exitcode}); close this vector env and build a new one"
        )
        raise WorkerError(self._broken) from cause


def _rebuild_error(payload: tuple[BaseException | None, str, str]) -> BaseException:
    """The exception a worker sent back (its original type when it could be pickled)."""
    error, text, trace = payload
    if error is None:
        return WorkerError(f"{text}\n--- worker traceback ---\n{trace}")
    error.add_note(f"--- raised in a BatchedWorkers process ---\n{trace}")
    return error


def _worker(
    conn: Connection,
    parent: Connection,
    env_fns: _Pickled,
    bounds: tuple[int, int, int],
    obs_space: gym.Space[Any],
    act_space: gym.Space[Any],
    shm: tuple[Any, Any, Any, Any],
    autoreset_mode: str,
) -> None:
    """A worker process: build the batch of envs, then serve commands until ``close``."""
    parent.close()
    lo, hi, n = bounds
    mode = AutoresetMode(autoreset_mode)
    obs_shm, act_shm, rew_shm, flag_shm = shm
    box_obs = isinstance(obs_space, spaces.Box)
    box_act = isinstance(act_space, spaces.Box)
    obs: Any = read_from_shared_memory(obs_space, obs_shm, n)
    actions: Any = read_from_shared_memory(act_space, act_shm, n)
    batched_act = batch_space(act_space, n)
    rewards = np.frombuffer(rew_shm, dtype=np.float64)
    flags = np.frombuffer(flag_shm, dtype=np.bool_).reshape(2, n)
    terminated, truncated = flags[0], flags[1]
    envs: list[gym.Env[Any, Any]] = []
    autoreset = [False] * (hi - lo)

    def put(i: int, value: Any) -> None:
        if box_obs:
            obs[i] = value
        else:
            write_to_shared_memory(obs_space, i, value, obs_shm)

    while True:
        try:
            if not envs:
                envs = [fn() for fn in env_fns.value]
                for env in envs:
                    if env.observation_space != obs_space or env.action_space != act_space:
                        raise ValueError(
                            "the envs of a vector env need the same spaces: "
                            f"{env.observation_space}, {env.action_space} differ from "
                            f"{obs_space}, {act_space}"
                        )
                conn.send((True, None))
            cmd, data = conn.recv()
            if cmd == "step":
                if box_act:
                    batch = [actions[i].copy() for i in range(lo, hi)]
                else:
                    batch = list(iterate(batched_act, actions))[lo:hi]
                infos: list[StepInfo] = []
                for j, env in enumerate(envs):
                    i = lo + j
                    final = None
                    r: Any
                    if mode is AutoresetMode.NEXT_STEP and autoreset[j]:
                        value, info = env.reset()
                        r, te, tr = 0.0, False, False
                    else:
                        if mode is AutoresetMode.DISABLED and autoreset[j]:
                            raise RuntimeError(
                                f"env {i} stepped after its episode ended; with autoreset "
                                "mode Disabled, reset it first (options={'reset_mask': ...})"
                            )
                        value, r, te, tr, info = env.step(batch[j])
                        if mode is AutoresetMode.SAME_STEP and (te or tr):
                            final = {"final_obs": value, "final_info": info}
                            value, info = env.reset()
                    put(i, value)
                    rewards[i], terminated[i], truncated[i] = r, te, tr
                    autoreset[j] = bool(te or tr)
                    infos.append((final, info))
                conn.send((True, infos))
            elif cmd == "reset":
                seeds, options, mask = data
                reset_infos: list[dict[str, Any] | None] = []
                for j, env in enumerate(envs):
                    if mask is not None and not mask[j]:
                        reset_infos.append(None)
                        continue
                    value, info = env.reset(seed=seeds[j], options=options[j])
                    put(lo + j, value)
                    terminated[lo + j] = truncated[lo + j] = False
                    autoreset[j] = False
                    reset_infos.append(info)
                conn.send((True, reset_infos))
            elif cmd in ("call", "get_attr", "set_attr", "is_wrapped"):
                what, local, values = data
                out = []
                for pos, j in enumerate(local):
                    env = envs[j]
                    if cmd == "call":
                        name, args, kwargs = what
                        attr = env.get_wrapper_attr(name)
                        out.append(attr(*args, **kwargs) if callable(attr) else attr)
                    elif cmd == "get_attr":
                        out.append(env.get_wrapper_attr(what))
                    elif cmd == "set_attr":
                        env.set_wrapper_attr(what, values[pos])
                        out.append(None)
                    else:
                        out.append(_is_wrapped(env, what))
                conn.send((True, out))
            elif cmd == "close":
                for env in envs:
                    env.close()
                conn.send((True, None))
                break
            else:  # pragma: no cover - the parent sends only the commands above
                raise RuntimeError(f"unknown command {cmd!r}")
        except (EOFError, KeyboardInterrupt, BrokenPipeError):
            break  # the parent is gone (or interrupted): nothing to answer to
        except BaseException as e:
            trace = traceback.format_exc()
            try:
                conn.send((False, (e, f"{type(e).__name__}: {e}", trace)))
            except Exception:  # the exception itself cannot be pickled: send its text
                try:
                    conn.send((False, (None, f"{type(e).__name__}: {e}", trace)))
                except OSError:
                    break
            if not envs:
                break  # the envs could not be built: this worker is useless
    for env in envs:
        with contextlib.suppress(Exception):
            env.close()
    conn.close()


class _Pickled:
    """A value pickled with cloudpickle (env functions may be closures or lambdas)."""

    def __init__(self, value: Any) -> None:
        self.value = value

    def __getstate__(self) -> bytes:
        import cloudpickle

        return cloudpickle.dumps(self.value)

    def __setstate__(self, state: bytes) -> None:
        import pickle

        self.value = pickle.loads(state)  # our own env functions, never a file


def _is_wrapped(env: gym.Env[Any, Any], wrapper_class: type) -> bool:
    current: Any = env
    while isinstance(current, gym.Wrapper):
        if isinstance(current, wrapper_class):
            return True
        current = current.env
    return isinstance(current, wrapper_class)

"""Evaluating a policy on an ``IAS-*`` environment: success rate, return, task errors, video.

:func:`evaluate` takes a policy object with SB3's ``predict`` (as SB3's ``evaluate_policy``
does); :func:`evaluate_spec` is its convenience from strings (env id, policy spec), whose
episodes (:class:`EpisodeJob`, one per seed) run here, on local worker processes or on Ray
(:mod:`ias_gym.runtime.jobs`) with the same results. Policies
are loaded by :func:`ias_gym.baselines.policies.load_policy` (re-exported here with
its errors, :data:`TELEOP` and :data:`Policy`, for the callers that import them from here).
The outcomes and their summary are :mod:`ias_gym.evaluation_results`'s; nearby starts of a
seed (1e-9 away) are :mod:`ias_gym.perturbed_starts`'s.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import imageio.v2 as imageio
import numpy as np
from tqdm import tqdm

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.baselines.policies import (  # re-exported: the loader's home is the policy layer
    TELEOP,
    MissingDependencyError,
    Policy,
    PolicyNotFoundError,
    RandomPolicy,
    load_policy,
)
from ias_gym.errors import (
    IasGymError,
    InputError,
    UnknownEnvError,
)
from ias_gym.evaluation_results import EpisodeOutcome, EvaluationResult
from ias_gym.outputs import atomic_output, check_output_file
from ias_gym.rollout import FrameRecorder, rollout
from ias_gym.runtime.jobs import SERIAL, Backend, prepare_here, run_jobs, worker_resource

#: Frame rate of evaluation videos [1/s]; the env's frames are thinned to it.
VIDEO_FPS = 25
#: File name suffixes of evaluation videos (ffmpeg picks the container by it).
VIDEO_SUFFIXES = (".mp4",)


def make_env(env_id: str, **kwargs: Any) -> gym.Env[Any, Any]:
    """``gym.make(env_id, **kwargs)`` with the user's mistakes reported as :class:`InputError`.

    Args:
        env_id: a registered id, e.g. ``"IAS-PenSlide-v0"``.
        **kwargs: configuration overrides (and ``render_mode``) passed to the env.

    Raises:
        UnknownEnvError: ``env_id`` is not registered (the message lists the IAS ids).
        InputError: the env refused ``kwargs`` (unknown, ill-typed or out of range; the
            message names them and, for the IAS envs, lists the known ones).
    """
    check_env_id(env_id)
    try:
        return gym.make(env_id, **kwargs)
    except IasGymError:
        raise
    except (TypeError, ValueError) as exc:
        # Raised while the env is built from kwargs: the kwargs are what is wrong. gymnasium
        # appends where it was raised, which the message below says already.
        reason = " ".join(str(exc).split()).split(" was raised from the environment creator")[0]
        raise InputError(f"{env_id} does not accept env kwargs {kwargs}: {reason}") from exc


def check_env_id(env_id: str) -> None:
    """Check that gymnasium knows ``env_id`` (without making the env).

    Raises:
        UnknownEnvError: ``env_id`` is not registered (the message lists the IAS ids).
    """
    try:
        gym.spec(env_id)
    except gym.error.Error as exc:
        ids = ", ".join(sorted(i for i in gym.registry if i.startswith("IAS-")))
        raise UnknownEnvError(
            f"unknown env id {env_id!r} ({' '.join(str(exc).split())}); the IAS envs are: {ids}"
        ) from None


def run_episode(
    env: gym.Env[Any, Any],
    policy: Policy,
    seed: int,
    *,
    reset_options: Mapping[str, Any] | None = None,
    frames: list[np.ndarray] | None = None,
    stride: int = 1,
) -> EpisodeOutcome:
    """Run one episode of ``policy`` from ``env.reset(seed=seed)``.

    The episode is :func:`ias_gym.rollout.rollout`'s: the first ``predict`` gets
    ``episode_start=True`` and ``state=None`` (a stateful policy, the expert's controller,
    starts afresh); later steps pass the state the previous call returned. Actions are
    deterministic.

    Args:
        env: the env (not closed here).
        policy: an object with SB3's ``predict``.
        seed: the reset seed.
        reset_options: ``options`` of ``env.reset`` (see :func:`evaluate`).
        frames: if given, ``env.render()`` before every ``stride``-th action is appended.
        stride: the frame stride (>= 1).

    Returns:
        The outcome.
    """
    grab = None if frames is None else FrameRecorder(stride, frames)
    trajectory = rollout(
        env,
        policy,
        seed,
        reset_options=reset_options,
        keep_observations=False,
        keep_infos=False,
        on_reset=None if grab is None else grab.on_reset,
        on_step=None if grab is None else grab.on_step,
    )
    if frames is not None and trajectory.length % stride == 0:
        frames.pop()  # a video shows the state before each action, not after the last one
    metrics = env.unwrapped.episode_metrics(trajectory.final_info)  # type: ignore[attr-defined]
    return EpisodeOutcome(
        bool(trajectory.final_info["is_success"]),
        trajectory.episode_return,
        trajectory.length,
        metrics,
    )


def seed_policy(policy: Policy, seed: int) -> None:
    """Seed ``policy`` for the episode of ``seed``: the ``random`` policy samples its actions
    from a stream seeded with the episode's seed (the others are deterministic).

    What makes an episode depend on its seed alone, not on the episodes run before it in
    the same process: a worker that runs seeds 3 and 7 gives what a serial run gives.
    """
    if isinstance(policy, RandomPolicy):
        policy.space.seed(seed)


@dataclass(frozen=True)
class EpisodeJob:
    """One seeded episode of a policy spec on an env spec: the job that
    :func:`~ias_gym.runtime.jobs.run_jobs` maps over seeds (``job(seed) -> EpisodeOutcome``).

    The process that runs it builds the env and loads the policy from the spec (once per
    process, :func:`~ias_gym.runtime.jobs.worker_resource`) and seeds the policy with the
    episode's seed (:func:`seed_policy`), so the outcome depends on the seed alone.

    Attributes:
        env_id: a registered id.
        policy: a policy spec (:func:`load_policy`).
        env_kwargs: configuration overrides for ``gym.make``.
        trust_pickle: as for :func:`load_policy`.
        reset_options: ``options`` of every episode's ``env.reset``.
    """

    env_id: str
    policy: str = "expert"
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    trust_pickle: bool = False
    reset_options: Mapping[str, Any] | None = None

    def key(self) -> tuple[str, str, str, bool]:
        """What identifies the env and policy a worker builds for this job."""
        kwargs = json.dumps(dict(self.env_kwargs), sort_keys=True, default=repr)
        return (self.env_id, kwargs, self.policy, self.trust_pickle)

    def build(self) -> tuple[gym.Env[Any, Any], Policy]:
        """Make the env and load the policy for it (seeded per episode, not here)."""
        env = make_env(self.env_id, **self.env_kwargs)
        try:
            return env, load_policy(self.policy, env, None, trust_pickle=self.trust_pickle)
        except BaseException:
            env.close()
            raise

    def __call__(self, seed: int) -> EpisodeOutcome:
        """Run the episode of ``seed``."""
        env, policy = worker_resource(self.key(), self.build)
        seed_policy(policy, seed)
        return run_episode(env, policy, seed, reset_options=self.reset_options)


def evaluate(
    env: gym.Env[Any, Any],
    policy: Policy,
    episodes: int = 10,
    seed: int = 0,
    *,
    name: str | None = None,
    video: Path | None = None,
    progress: bool = False,
    overwrite: bool = False,
    reset_options: Mapping[str, Any] | None = None,
) -> EvaluationResult:
    """Run ``policy`` for ``episodes`` episodes (seeds ``seed, seed+1, ...``) and collect the
    outcomes, as SB3's ``evaluate_policy`` does with any object that has ``predict``.

    Each episode's first ``predict`` gets ``episode_start=True`` (a stateful policy, such
    as the expert's controller, starts afresh) and ``state=None``; later steps pass the
    state the previous call returned. Actions are deterministic.

    Args:
        env: the env ``policy`` was loaded for (not closed here).
        policy: an object with SB3's ``predict`` (:class:`~ias_gym.baselines.policies.Policy`;
            :func:`load_policy` makes one from a command-line spec).
        episodes: number of episodes (>= 1).
        seed: seed of the first episode (>= 0).
        name: the policy's name in the result (default: its class name).
        video: if given, an MP4 of the first episode is written there; ``env`` must have
            been made with ``render_mode="rgb_array"`` (see :func:`evaluate_spec`).
        progress: show a progress bar over episodes.
        overwrite: replace an existing ``video`` file.
        reset_options: ``options`` of every episode's ``env.reset`` (``None``: the seed's
            own start). For the pen tasks ``{"qpos": ..., "qvel": ...}`` starts from that
            exact MuJoCo state ([m, rad], [m/s, rad/s]), the same one in every episode, so
            pass it with ``episodes=1``: e.g. a start perturbed by 1e-9 to check that a
            closed-loop result is not a knife edge of this machine's arithmetic.

    Raises:
        InputError: bad ``episodes``/``seed``, an unusable ``video`` path, or a ``video``
            asked of an env that does not render ``rgb_array``.
        OutputExistsError: ``video`` exists and ``overwrite`` is false.
    """
    check_run(episodes, seed)
    if video is not None:  # before any work: a bad path must not cost an episode
        video = check_output_file(video, overwrite=overwrite, suffixes=VIDEO_SUFFIXES, what="video")
        if env.render_mode != "rgb_array":
            raise InputError(
                f"a video needs the env made with render_mode='rgb_array', got {env.render_mode!r}"
            )
    env_id = env.spec.id if env.spec is not None else type(env.unwrapped).__name__
    name = name or type(policy).__name__
    result = EvaluationResult(env_id=env_id, policy=name)
    fps = float(env.metadata.get("render_fps", 50))
    stride = max(1, round(fps / VIDEO_FPS))  # render only the frames the video keeps
    episode_iter: Any = range(episodes)
    if progress:
        episode_iter = tqdm(episode_iter, desc=f"{env_id} / {name}", unit="episode")
    for episode in episode_iter:
        frames: list[np.ndarray] | None = [] if (video is not None and episode == 0) else None
        outcome = run_episode(
            env, policy, seed + episode, reset_options=reset_options, frames=frames, stride=stride
        )
        result.add(outcome)
        if frames is not None and video is not None:
            write_video(video, frames, fps=fps / stride, overwrite=overwrite)
    return result


def check_run(episodes: int, seed: int) -> None:
    """Check an episode count and a first seed.

    Raises:
        InputError: ``episodes`` < 1 or ``seed`` < 0.
    """
    if episodes < 1:
        raise InputError(f"episodes must be >= 1, got {episodes}")
    if seed < 0:
        raise InputError(f"seed must be >= 0 (numpy seeds are non-negative), got {seed}")


def evaluate_spec(
    env_id: str,
    policy: str = "expert",
    episodes: int = 10,
    seed: int = 0,
    video: Path | None = None,
    progress: bool = False,
    env_kwargs: dict[str, Any] | None = None,
    *,
    overwrite: bool = False,
    trust_pickle: bool = False,
    reset_options: Mapping[str, Any] | None = None,
    backend: Backend | None = None,
) -> EvaluationResult:
    """Evaluate a policy spec on an env id, for the command line and tests: episodes of
    seeds ``seed, seed + 1, ...``, each an :class:`EpisodeJob` run on ``backend`` (here, on
    local worker processes or on Ray), each with the policy seeded by its episode's seed
    (:func:`seed_policy`): the result is the same on every backend, bit for bit.

    Args:
        env_id: a registered id, e.g. ``"IAS-PenSlide-v0"``.
        policy: ``"expert"``, ``"teleop"``, ``"random"`` or a path to a saved SB3 model
            (:func:`load_policy`); also the policy's name in the result.
        episodes: number of episodes (>= 1).
        seed: seed of the first episode (>= 0); episode ``i`` (and the ``random`` policy's
            sampling in it) is seeded with ``seed + i``.
        video: if given, an MP4 of the first episode is written there (needs ``MUJOCO_GL``
            set for headless rendering, e.g. ``egl``); that episode runs in this process.
            Checked before the env is built: its directory must exist and be writable.
        progress: show a progress bar over episodes (on stderr).
        env_kwargs: configuration overrides passed to ``gym.make``.
        overwrite: replace an existing ``video`` file.
        trust_pickle: load a model file with SB3's own ``load`` (runs code from the file).
        reset_options: as for :func:`evaluate`.
        backend: where the episodes run (:class:`~ias_gym.runtime.jobs.Backend`; default: here).

    Raises:
        InputError: bad ``episodes``/``seed``, unusable ``video`` path, unknown env id or
            env kwargs, or a policy that cannot be loaded for this env (see
            :func:`make_env`, :func:`load_policy`).
        OutputExistsError: ``video`` exists and ``overwrite`` is false.
        WorkerError: a worker process died twice running the same episode.
    """
    check_run(episodes, seed)
    if video is not None:  # before the env is built: a bad path must not cost its build
        video = check_output_file(video, overwrite=overwrite, suffixes=VIDEO_SUFFIXES, what="video")
    check_env_id(env_id)  # before workers start: an unknown id fails here, at once
    job = EpisodeJob(env_id, policy, dict(env_kwargs or {}), trust_pickle, reset_options)
    backend = backend or SERIAL
    prepare_here(job.key(), job.build, backend)  # a bad kwarg or policy fails here, at once
    result = EvaluationResult(env_id=env_id, policy=policy)
    seeds = list(range(seed, seed + episodes))
    if video is not None:  # the first episode is rendered here, the others run anywhere
        result.add(_video_episode(job, seeds.pop(0), video, overwrite=overwrite))
    for outcome in run_jobs(job, seeds, backend, desc=f"{env_id} / {policy}", progress=progress):
        result.add(outcome)
    return result


def _video_episode(job: EpisodeJob, seed: int, video: Path, *, overwrite: bool) -> EpisodeOutcome:
    """Run ``job``'s episode of ``seed`` here in an env that renders, and write its video.

    Rendering reads the simulation without changing it: the outcome is the one a worker
    computes without rendering.
    """
    os.environ.setdefault("MUJOCO_GL", "egl")
    env = make_env(job.env_id, **{**job.env_kwargs, "render_mode": "rgb_array"})
    try:
        act = load_policy(job.policy, env, None, trust_pickle=job.trust_pickle)
        seed_policy(act, seed)
        fps = float(env.metadata.get("render_fps", 50))
        stride = max(1, round(fps / VIDEO_FPS))  # render only the frames the video keeps
        frames: list[np.ndarray] = []
        outcome = run_episode(
            env, act, seed, reset_options=job.reset_options, frames=frames, stride=stride
        )
        write_video(video, frames, fps=fps / stride, overwrite=overwrite)
        return outcome
    finally:
        env.close()


def report(env_id: str, policy: str, episodes: int, seed: int, what: str = "policy") -> None:
    """Evaluate ``policy`` over ``episodes`` episodes (none if < 1) and print one summary line.

    What the ``train/`` scripts print after training, and the command to evaluate further.
    """
    if episodes >= 1:
        summary = evaluate_spec(env_id, policy, episodes, seed=seed, progress=True).summary()
        print(
            f"{what} on {env_id}: success {summary['success_rate']:.0%} over {episodes} "
            f"episodes, mean return {summary['mean_return']:.1f}"
        )
    print(f"evaluate with: ias-gym evaluate --env {env_id} --policy {policy} --episodes 100")


def write_video(
    path: Path, frames: list[np.ndarray], fps: float, *, overwrite: bool = False
) -> Path:
    """Write RGB frames to an MP4 with imageio: into a temporary file in the same directory,
    renamed to ``path`` when complete (a reader never sees half a video).

    Args:
        path: the video file; its directory must exist.
        frames: ``(H, W, 3)`` uint8 images.
        fps: frame rate [1/s].
        overwrite: replace an existing ``path``.

    Raises:
        OutputExistsError: ``path`` exists and ``overwrite`` is false.
    """
    path = Path(path)
    with atomic_output(path, overwrite=overwrite) as tmp:
        writer: Any = imageio.get_writer(tmp, fps=fps, macro_block_size=8)
        with writer:
            for frame in frames:
                writer.append_data(frame)
    return path


__all__ = [
    "TELEOP",
    "VIDEO_FPS",
    "VIDEO_SUFFIXES",
    "EpisodeJob",
    "MissingDependencyError",
    "Policy",
    "PolicyNotFoundError",
    "UnknownEnvError",
    "check_env_id",
    "check_run",
    "evaluate",
    "evaluate_spec",
    "load_policy",
    "make_env",
    "report",
    "run_episode",
    "seed_policy",
    "write_video",
]

"""Evaluating a policy on an ``IAS-*`` environment: success rate, return, task errors, video.

:func:`evaluate` takes a policy object with SB3's ``predict`` (as SB3's ``evaluate_policy``
does); :func:`evaluate_spec` is its convenience from strings (env id, policy spec). Policies
are loaded by :func:`ias_gym.baselines.policies.load_policy` (re-exported here with
its errors, :data:`TELEOP` and :data:`Policy`, for the callers that import them from here).
"""

from __future__ import annotations

import math
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
    load_policy,
)
from ias_gym.errors import IasGymError, InputError
from ias_gym.outputs import atomic_output, check_output_file

#: Frame rate of evaluation videos [1/s]; the env's frames are thinned to it.
VIDEO_FPS = 25
#: File name suffixes of evaluation videos (ffmpeg picks the container by it).
VIDEO_SUFFIXES = (".mp4",)
#: Unit of each task metric in the summary: ``metric -> (summary name, unit, factor)``; the
#: envs report SI (m, rad, N), the summary mm, deg and percent, named in every key.
METRIC_UNITS: Mapping[str, tuple[str, str, float]] = {
    "final_slide_error": ("final_slide_error", "mm", 1e3),
    "max_position_error": ("max_position_error", "mm", 1e3),
    "max_pen_tilt": ("max_pen_tilt", "deg", math.degrees(1.0)),
    "rms_tilt_error": ("rms_tilt_error", "deg", math.degrees(1.0)),
    "rms_tilt_error_fraction": ("rms_tilt_error_of_amplitude", "pct", 100.0),
    "pen_height": ("pen_height", "mm", 1e3),
    "pinch_force": ("pinch_force", "N", 1.0),
}


class UnknownEnvError(InputError, LookupError):
    """An env id that gymnasium does not know (the message lists the ``IAS-*`` ids)."""


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
    try:
        gym.spec(env_id)
    except gym.error.Error as exc:
        ids = ", ".join(sorted(i for i in gym.registry if i.startswith("IAS-")))
        raise UnknownEnvError(
            f"unknown env id {env_id!r} ({' '.join(str(exc).split())}); the IAS envs are: {ids}"
        ) from None
    try:
        return gym.make(env_id, **kwargs)
    except IasGymError:
        raise
    except (TypeError, ValueError) as exc:
        # Raised while the env is built from kwargs: the kwargs are what is wrong. gymnasium
        # appends where it was raised, which the message below says already.
        reason = " ".join(str(exc).split()).split(" was raised from the environment creator")[0]
        raise InputError(f"{env_id} does not accept env kwargs {kwargs}: {reason}") from exc


@dataclass
class EvaluationResult:
    """Per-episode outcomes and their summary (see :meth:`summary`)."""

    env_id: str
    policy: str
    successes: list[bool] = field(default_factory=list)
    returns: list[float] = field(default_factory=list)
    lengths: list[int] = field(default_factory=list)
    metrics: list[dict[str, float]] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary: success rate, mean return, and mean/max of each task metric.

        Each metric's keys name its statistic and unit, ``<metric>_<mean|max>_<unit>``
        (``max_position_error_max_mm``, ``max_pen_tilt_mean_deg``, ``pinch_force_max_N``,
        :data:`METRIC_UNITS`); a metric without a known unit keeps the env's SI value
        and ends in ``_si``. ``None``: the metric was not defined in any episode.
        """
        out: dict[str, Any] = {
            "env": self.env_id,
            "policy": self.policy,
            "episodes": len(self.successes),
            "success_rate": float(np.mean(self.successes)) if self.successes else 0.0,
            "mean_return": float(np.mean(self.returns)) if self.returns else 0.0,
            "mean_length": float(np.mean(self.lengths)) if self.lengths else 0.0,
        }
        for key in self.metrics[0] if self.metrics else ():
            name, unit, factor = METRIC_UNITS.get(key, (key, "si", 1.0))
            values = factor * np.array([m[key] for m in self.metrics])
            values = values[np.isfinite(values)]  # NaN: not defined for that episode
            out[f"{name}_mean_{unit}"] = float(values.mean()) if len(values) else None
            out[f"{name}_max_{unit}"] = float(values.max()) if len(values) else None
        return out


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
    _check_run(episodes, seed)
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
        options = dict(reset_options) if reset_options is not None else None
        obs, info = env.reset(seed=seed + episode, options=options)
        total, length, done = 0.0, 0, False
        state: Any = None
        while not done:
            if frames is not None and length % stride == 0:
                frames.append(env.render())  # type: ignore[arg-type]
            action, state = policy.predict(
                obs, state=state, episode_start=length == 0, deterministic=True
            )
            obs, reward, terminated, truncated, info = env.step(action)
            total += float(reward)
            length += 1
            done = terminated or truncated
        result.successes.append(bool(info["is_success"]))
        result.returns.append(total)
        result.lengths.append(length)
        result.metrics.append(env.unwrapped.episode_metrics(info))  # type: ignore[attr-defined]
        if frames is not None and video is not None:
            write_video(video, frames, fps=fps / stride, overwrite=overwrite)
    return result


def _check_run(episodes: int, seed: int) -> None:
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
) -> EvaluationResult:
    """:func:`evaluate` from strings, for the command line and tests: make the env, load the
    policy spec (:func:`load_policy`, seeded with ``seed``), evaluate, close the env.

    Args:
        env_id: a registered id, e.g. ``"IAS-PenSlide-v0"``.
        policy: ``"expert"``, ``"teleop"``, ``"random"`` or a path to a saved SB3 model
            (:func:`load_policy`); also the policy's name in the result.
        episodes: number of episodes (>= 1).
        seed: seed of the first episode (>= 0) and of the ``random`` policy's sampling.
        video: if given, an MP4 of the first episode is written there (needs ``MUJOCO_GL``
            set for headless rendering, e.g. ``egl``). Checked before the env is built:
            its directory must exist and be writable.
        progress: show a progress bar over episodes.
        env_kwargs: configuration overrides passed to ``gym.make``.
        overwrite: replace an existing ``video`` file.
        trust_pickle: load a model file with SB3's own ``load`` (runs code from the file).
        reset_options: as for :func:`evaluate`.

    Raises:
        InputError: bad ``episodes``/``seed``, unusable ``video`` path, unknown env id or
            env kwargs, or a policy that cannot be loaded for this env (see
            :func:`make_env`, :func:`load_policy`).
        OutputExistsError: ``video`` exists and ``overwrite`` is false.
    """
    _check_run(episodes, seed)
    if video is not None:  # before the env is built: a bad path must not cost its build
        video = check_output_file(video, overwrite=overwrite, suffixes=VIDEO_SUFFIXES, what="video")
    kwargs = dict(env_kwargs or {})
    if video is not None:
        os.environ.setdefault("MUJOCO_GL", "egl")
        kwargs["render_mode"] = "rgb_array"
    env = make_env(env_id, **kwargs)
    try:
        act = load_policy(policy, env, seed, trust_pickle=trust_pickle)
        return evaluate(
            env,
            act,
            episodes,
            seed,
            name=policy,
            video=video,
            progress=progress,
            overwrite=overwrite,
            reset_options=reset_options,
        )
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
    "METRIC_UNITS",
    "TELEOP",
    "VIDEO_FPS",
    "VIDEO_SUFFIXES",
    "EvaluationResult",
    "MissingDependencyError",
    "Policy",
    "PolicyNotFoundError",
    "UnknownEnvError",
    "evaluate",
    "evaluate_spec",
    "load_policy",
    "make_env",
    "report",
    "write_video",
]

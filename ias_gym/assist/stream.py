"""What the recogniser sees of a glove session, one control step at a time (paper Flow 3).

A :class:`SessionFrame` is the state of an ``IAS-GloveGrasp-v0`` session at one control step:
the glove's readings Ψ, the calibrated joint angles Θ that drive the virtual hand, the force
display and the pen's pose in the paper frame. Frames come from a live env
(:func:`frames_from_env`, once after ``reset`` and after every ``step``) or from a stored glove
skill (:func:`frames_from_skill`), so that a recogniser built from a skill database sees the
same quantities on line.

The env keeps Θ (its filtered calibrated angles) but not the raw readings Ψ: :func:`tap_glove`
wraps the env's glove factory so that every glove it opens remembers its last reading
(:class:`ReadingTap`); call it once before ``reset``. :func:`record_session` records a session
as a :class:`~ias_gym.skills.Skill` whose demonstration infos also hold Ψ and Θ
(``glove_readings``, ``glove_theta``), so :func:`frames_from_skill` rebuilds the frames exactly;
for a glove skill recorded without them (``ias-gym skills record``) Θ falls back to the hand's
joint angles in the observations (the position servos track Θ with a lag of a few 10 ms) and
Ψ to NaN.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ias_gym.envs.glove_world import OBSERVATION
from ias_gym.errors import InputError
from ias_gym.glove.device import GloveDevice, GloveReading, GloveWrapper
from ias_gym.glove.hand import JOINT_NAMES, N_JOINTS

if TYPE_CHECKING:
    import gymnasium as gym

    from ias_gym.envs.glove_grasp import GloveGraspEnv
    from ias_gym.skills import Skill

FloatArray = NDArray[np.float64]

#: Demonstration info keys under which :func:`record_session` stores Ψ and Θ ``(T + 1, 10)``.
READINGS_INFO = "glove_readings"
THETA_INFO = "glove_theta"
#: The glove observation's joint angles and force display (``IAS-GloveGrasp-v0``).
_OBS_JOINTS = OBSERVATION["joint_angles"]
_OBS_TAU = OBSERVATION["feedback_torques"]


@dataclass(frozen=True, eq=False)
class SessionFrame:
    """One control step of a glove session as the recogniser sees it.

    Attributes:
        time_s: time since the session's reset [s].
        readings: ``(10,)`` glove readings Ψ [rad] (order of
            :data:`~ias_gym.glove.hand.SENSOR_NAMES`; NaN where the source did not keep them).
        theta: ``(10,)`` calibrated joint angles Θ [rad] (order of
            :data:`~ias_gym.glove.hand.JOINT_NAMES`).
        tau_display: ``(5,)`` force-display torques [N m] on
            :data:`~ias_gym.glove.device.ACTUATED_JOINTS`.
        pen_position: ``(3,)`` pen centre relative to its nominal position [m], paper frame.
        pen_rpy: ``(3,)`` the pen's roll, pitch, yaw [rad], paper frame (eq. 25).
    """

    time_s: float
    readings: FloatArray
    theta: FloatArray
    tau_display: FloatArray
    pen_position: FloatArray
    pen_rpy: FloatArray


class ReadingTap(GloveWrapper):
    """A glove that passes everything to ``inner`` and keeps its last reading.

    Args:
        inner: the glove to wrap.
    """

    def __init__(self, inner: GloveDevice) -> None:
        super().__init__(inner)
        #: The last reading of :meth:`read` (``None`` before the first).
        self.last_reading: GloveReading | None = None

    def read(self) -> GloveReading:
        """Read ``inner`` and remember the reading."""
        self.last_reading = self.inner.read()
        return self.last_reading


def _glove_env(env: Any) -> GloveGraspEnv:
    from ias_gym.envs.glove_grasp import GloveGraspEnv  # MuJoCo: only when an env is given

    unwrapped = getattr(env, "unwrapped", env)
    if not isinstance(unwrapped, GloveGraspEnv):
        raise InputError(
            f"a glove session needs an IAS-GloveGrasp-v0 env (or one built on it), got "
            f"{type(unwrapped).__name__}"
        )
    return unwrapped


def tap_glove(env: gym.Env[Any, Any] | GloveGraspEnv) -> None:
    """Make every glove the env opens from now on keep its last reading (idempotent).

    Args:
        env: an ``IAS-GloveGrasp-v0`` env (wrappers allowed); call before ``reset``.

    Raises:
        InputError: not a glove env.
    """
    glove_env = _glove_env(env)
    factory = glove_env.glove_factory
    if getattr(factory, "taps_readings", False):
        return

    def tapped(seed: int) -> GloveDevice:
        return ReadingTap(factory(seed))

    tapped.taps_readings = True  # type: ignore[attr-defined]
    glove_env.glove_factory = tapped


def frames_from_env(env: gym.Env[Any, Any] | GloveGraspEnv) -> SessionFrame:
    """The frame of the env's session now (after ``reset`` or a ``step``).

    Args:
        env: an ``IAS-GloveGrasp-v0`` env (wrappers allowed). Ψ is filled in when
            :func:`tap_glove` was called before the ``reset``, else it is NaN.

    Returns:
        The frame (copies: later steps do not change it).

    Raises:
        InputError: not a glove env.
        RuntimeError: the env has not been reset.
    """
    e = _glove_env(env)
    if e.glove is None or e.contact_pass is None:
        raise RuntimeError("read the glove env's frame after reset() or step()")
    last = getattr(e.glove, "last_reading", None)
    readings = (
        np.array(last.psi, dtype=np.float64) if last is not None else np.full(N_JOINTS, np.nan)
    )
    position, rpy = e.physics.pen_pose()
    # The env's filtered calibrated angles: what drives the hand's position targets.
    theta = np.array(e._theta, dtype=np.float64)
    return SessionFrame(
        time_s=float(e.data.time),
        readings=readings,
        theta=theta,
        tau_display=np.array(e._feedback, dtype=np.float64),
        pen_position=np.array(position, dtype=np.float64),
        pen_rpy=np.array(rpy, dtype=np.float64),
    )


def frames_from_skill(skill: Skill) -> list[SessionFrame]:
    """The frames of a stored glove session, one per observation (``T + 1``).

    Args:
        skill: a glove skill (``IAS-GloveGrasp-v0``: 39-column observations). Ψ and Θ come
            from its infos ``glove_readings`` and ``glove_theta`` when it has them
            (:func:`record_session`); else Θ is the hand's joint angles of the observations
            and Ψ is NaN.

    Returns:
        The frames in time order.

    Raises:
        InputError: the skill is not a glove session (wrong observation size).
    """
    demo, model = skill.demonstration, skill.model
    obs = np.asarray(demo.observations, dtype=np.float64)
    if obs.ndim != 2 or obs.shape[1] != 39:
        raise InputError(
            f"skill {skill.id} ({skill.name!r}, task {skill.task}) is not a glove session: "
            f"observations of shape {obs.shape}, need (T + 1, 39) of IAS-GloveGrasp-v0"
        )
    n = len(obs)
    readings = demo.infos.get(READINGS_INFO)
    theta = demo.infos.get(THETA_INFO)
    psi = (
        np.asarray(readings, dtype=np.float64)
        if readings is not None
        else np.full((n, N_JOINTS), np.nan)
    )
    th = np.asarray(theta, dtype=np.float64) if theta is not None else obs[:, _OBS_JOINTS]
    return [
        SessionFrame(
            time_s=float(model.time[i]),
            readings=psi[i].copy(),
            theta=th[i].copy(),
            tau_display=obs[i, _OBS_TAU].copy(),
            pen_position=np.array(model.pen_position[i], dtype=np.float64),
            pen_rpy=np.array(model.pen_rpy[i], dtype=np.float64),
        )
        for i in range(n)
    ]


class _FramePolicy:
    """Zero action (teleoperation); reads the env's frame before every action."""

    def __init__(
        self,
        env: GloveGraspEnv,
        n_actions: int,
        on_frame: Callable[[SessionFrame], None] | None = None,
    ) -> None:
        self.env, self.n_actions, self.on_frame = env, n_actions, on_frame
        self.frames: list[SessionFrame] = []

    def observe(self) -> None:
        self.frames.append(frames_from_env(self.env))
        if self.on_frame is not None:
            self.on_frame(self.frames[-1])

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], None]:
        self.observe()
        return np.zeros(self.n_actions, dtype=np.float32), None


def record_session(
    env: gym.Env[Any, Any],
    *,
    seed: int,
    name: str | None = None,
    on_frame: Callable[[SessionFrame], None] | None = None,
) -> tuple[Skill, list[SessionFrame]]:
    """Record one teleoperated glove session as a skill with Ψ and Θ in its infos.

    Args:
        env: an ``IAS-GloveGrasp-v0`` env made with ``person_id`` and ``skill``
            (:func:`tap_glove` is applied to it).
        seed: the reset seed.
        name: the skill's name (default: the env's ``skill``).
        on_frame: called with every frame as the session runs (e.g. a recogniser's update).

    Returns:
        The skill (not stored; ``env_kwargs`` names the person and the skill) and its frames.

    Raises:
        InputError: not a glove env.
    """
    from ias_gym.skills import record_episode  # the skills layer: only when recording

    e = _glove_env(env)
    tap_glove(e)
    policy = _FramePolicy(e, len(JOINT_NAMES), on_frame)
    kwargs = {"person_id": e.person.person_id, "skill": e.config.skill}
    skill = record_episode(env, policy, seed=seed, source="teleop", name=name, env_kwargs=kwargs)
    policy.observe()  # the state after the last step
    frames = policy.frames
    infos = dict(skill.demonstration.infos)
    infos[READINGS_INFO] = np.stack([f.readings for f in frames])
    infos[THETA_INFO] = np.stack([f.theta for f in frames])
    demo = dataclasses.replace(skill.demonstration, infos=infos)
    return dataclasses.replace(skill, demonstration=demo), frames


def session_frames(sessions: Sequence[Skill]) -> list[list[SessionFrame]]:
    """:func:`frames_from_skill` of each skill."""
    return [frames_from_skill(s) for s in sessions]

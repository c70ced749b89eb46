"""The assistant as a policy on observations: it completes the skill it recognises (Flow 3).

Paper, Flow 3: the system "identifies and anticipates the action the human operator wants
to perform, and if the necessary skill has been stored in the skill data base before, it is
applied": the operator only gives the goal. :func:`make_assistant` builds an
:class:`ObservationAssistant` from a skill database; it has ``reset()`` and
``act(observation) -> action`` and reads nothing but the observation (by the env's part
names, :mod:`ias_gym.envs.layout`) and the database: no env object, configuration, person
id or simulator state. On ``IAS-GloveAssist-v0`` the operator's joint targets are the
observation's ``upcoming_theta``; on an env without them (``IAS-GloveHardware-v0``) they
are the hand's ``joint_angles`` less the assistant's own last offset.

Every step:

0. **Tremor.** :class:`~ias_gym.assist.tremor.TremorCanceller` notches the strongest line
   of the tremor band (4-12 Hz) out of the operator's targets where it is strong enough to
   be a tremor (``tremor_floor_rad``), and what follows reads the targets without it.
1. **Recognition.** The observation becomes a
   :class:`~ias_gym.assist.stream.SessionFrame` (:func:`frame_from_observation`) and the
   recogniser (:mod:`ias_gym.assist.recognition`) updates its posterior ``p_k`` over the
   library's skills and ``unknown``.
2. **Completion from the recognised skill's stored model.** Each skill's template
   (:class:`~ias_gym.assist.skill_motions.SkillMotion`: its demonstrations' joint
   trajectories from their skill start, aligned in amplitude and speed and averaged, less
   the pose at the start) says how the skill moves the joints it moves. For each skill the
   assistant fits the operator's own version of it to what the operator has done since the
   skill's motion set in: amplitude ``a``, speed ``v`` and start ``t0``, the most probable
   under the library's spread of persons and the operator's own unsteadiness before the
   motion, so that ``a m_k(v (t - t0))`` is this person's motion. When the operator's
   motion falls short of the fitted model's (their speed over ``stop_window_s`` below
   ``stop_ratio`` of the model's, on the skill's principal joint, with at least
   ``min_remaining_rad`` of the model's motion still to go from the operator's pose: the
   fields of :class:`~ias_gym.assist.motion_completion.AssistParams`), the fit is held, and once
   that has lasted ``stop_hold_s`` the assistant latches that the operator has stopped. It
   completes the skill the recogniser put first when the operator began to slow down
   (one skill: two completions at once would move the same joints two ways), driving its
   principal joint the rest of the way: from the stopped pose, catching up with the fitted
   timeline at ``catch_up_pace`` times its pace, offset
   ``= p_k (a m_k(v (t - t0)) - (Θ - Θ_0))`` with ``p_k`` the skill's posterior when the
   slowing down began (the ``unknown`` share adds nothing, so without skill knowledge
   there is no completion; what the recogniser sees afterwards is the completion itself,
   no evidence of what the operator meant).
   Once the fitted motion is done, the assistant holds the pen where the skill's
   demonstrations leave it, as the person in the loop would by sight and the stopped
   operator no longer does: the pen's height error against the skill's
   :attr:`~ias_gym.assist.skill_motions.SkillMotion.goal_height` is integrated into the
   wrist's flexion through the lifts' ``rise_per_flexion``, and its axis' elevation error
   against the operator's tilt (``a`` times the skill's ``tilt_per_amplitude`` from the
   elevation at ``t0``) into the pronation through ``tilt_per_pronation`` (all from the
   demonstrations), at ``sight_gain``, weighted by ``p_k`` as well.

3. **Both pads on the pen.** :class:`~ias_gym.assist.pad_contact.PadKeeper` reads the
   force display: a finger whose pad is off the pen while the other's is on, for longer
   than the library's pads took to meet (counted from the first touch of a demonstrator's
   pad on: before, a pad on the pen rests on it), is closed along the library's closing
   direction at ``pad_close_rate`` (the skills pinch the pen from the close to the end: a
   weak grip or an opening calibration otherwise lets it go in the lift).

4. **Acquisition** (between sessions): :meth:`ObservationAssistant.learn` stores a recorded
   demonstration the recogniser calls unknown as a new skill of the assistant's library,
   and from the next session on the assistant recognises and completes it.

The thresholds are :class:`~ias_gym.assist.motion_completion.AssistParams`, fitted on development
persons by ``train/fit_assistant.py`` and stored in ``ias_gym/assets/assistant_params.json``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from ias_gym.assist.motion_completion import PARAMS_PATH, REFIT_EVERY, AssistParams, Completion
from ias_gym.assist.pad_contact import PadKeeper, PinchClosing, pinch_closing
from ias_gym.assist.recogniser_registry import METHODS, make_recogniser
from ias_gym.assist.recognition import Acquisition, learn_demonstration
from ias_gym.assist.sessions import LIFT_END
from ias_gym.assist.skill_motions import (
    WRIST_FLEXION,
    WRIST_PRONATION,
    SkillMotion,
    load_motions,
    pen_elevation,
)
from ias_gym.assist.stream import SessionFrame
from ias_gym.assist.tremor import TremorCanceller
from ias_gym.errors import InputError
from ias_gym.glove.hand import N_JOINTS
from ias_gym.sim.pen import R_PAPER_TO_MJ, matrix_to_rpy, mj_to_paper
from ias_gym.skills.db import SkillDB
from ias_gym.skills.skill import Skill
from ias_gym.skills.transfer import shipped_skill_db

FloatArray = NDArray[np.float64]

#: Recognisers by name: the library's (:data:`~ias_gym.assist.recogniser_registry.METHODS`) and
#: ``"none"``, which always says ``unknown`` (the "no skill knowledge" ablation).
RECOGNISERS = (*METHODS, "none")


def frame_from_observation(
    obs: FloatArray, layout: Mapping[str, slice], theta: FloatArray
) -> SessionFrame:
    """The recogniser's frame of an observation: its time, force display and the pen's pose
    (turned into the paper frame), with the operator's joint targets ``theta`` (the glove's
    raw readings are no part of the observation: NaN)."""
    flat = np.zeros(9)
    mujoco.mju_quat2Mat(flat, np.asarray(obs[layout["pen_quat"]], dtype=np.float64))
    rot_mj = flat.reshape(3, 3)
    return SessionFrame(
        time_s=float(obs[layout["time"]][0]),
        readings=np.full(N_JOINTS, np.nan),
        theta=np.array(theta, dtype=np.float64),
        tau_display=np.array(obs[layout["feedback_torques"]], dtype=np.float64),
        pen_position=mj_to_paper(obs[layout["pen_position"]]),
        pen_rpy=matrix_to_rpy(R_PAPER_TO_MJ.T @ rot_mj @ R_PAPER_TO_MJ),
    )


class _NoRecogniser:
    """Always ``unknown``: the assistant without skill knowledge."""

    skills: tuple[str, ...] = ()

    def reset(self) -> None:
        """Nothing to forget."""

    def update(self, frame: SessionFrame) -> dict[str, float]:
        """Posterior 1 on ``unknown``."""
        return {"unknown": 1.0}


class ObservationAssistant:
    """Completes the recognised skill, from observations alone (module docstring).

    Args:
        motions: the library's skill motions (:func:`~ias_gym.assist.skill_motions.load_motions`).
        recogniser: the recogniser (the protocol of :mod:`ias_gym.assist.recognition`).
        params: the fitted thresholds.
        control_dt: the env's step [s].
        action_scale: the env's joint offset of a full action [rad].
        layout: the env's observation layout (``env.unwrapped.observation_layout``).
        completion: switch the completion off (an ablation).
        tremor: switch the tremor canceller off (an ablation).
        closing: the library's pinches (:func:`~ias_gym.assist.pad_contact.pinch_closing`);
            None: no pad keeping (an ablation).
        library: the skill database the motions came from (:meth:`learn` adds to it).
    """

    #: It acts on the observation, not on an env
    #: (:class:`~ias_gym.assist.sessions.AssistantPolicy`).
    reads_observations = True

    def __init__(
        self,
        motions: Mapping[str, SkillMotion],
        recogniser: Any,
        params: AssistParams,
        *,
        control_dt: float = 0.01,
        action_scale: float = 0.2,
        layout: Mapping[str, slice] | None = None,
        completion: bool = True,
        tremor: bool = True,
        closing: PinchClosing | None = None,
        library: str | Path | None = None,
    ) -> None:
        self.motions = dict(motions)
        self.library = Path(library) if library is not None else None
        self.recogniser = recogniser
        self.params = params
        self.dt = float(control_dt)
        self.scale = float(action_scale)
        self.layout = dict(layout) if layout is not None else None
        self.completion = completion
        self.tremor = (
            TremorCanceller(
                self.dt,
                params.tremor_window_s,
                trend_degree=params.tremor_trend_degree,
                floor_rad=params.tremor_floor_rad,
            )
            if tremor
            else None
        )
        self.pads = (
            None
            if closing is None
            else PadKeeper(closing, params.pad_close_rate, self.scale, self.dt)
        )
        self.reset()

    def reset(self) -> None:
        """Start a session: forget the last one's state."""
        self.recogniser.reset()
        if self.tremor is not None:
            self.tremor.reset()
        if self.pads is not None:
            self.pads.reset()
        self._post: dict[str, float] = {}
        self._last_offset = np.zeros(N_JOINTS)
        self._theta0: FloatArray | None = None  # the operator's pose at the lift's end
        self._fits = {k: Completion(m, self.params, self.dt) for k, m in self.motions.items()}
        #: The skill being completed: the first whose stop was latched while the recogniser
        #: put it first.
        self._active: str | None = None
        self._authority = 0.0  # its weight: its posterior when the operator slowed down
        #: the wrist flexion and pronation that hold the pen at the skill's goal [rad]
        self._hold = np.zeros(N_JOINTS)
        self._times: list[float] = []  # the session's step times [s] ...
        self._tilts: list[float] = []  # ... and the pen's axis elevation then [rad]
        self._posts: list[dict[str, float]] = []
        self._steps = 0

    def learn(
        self, db: SkillDB, skill: Skill, frames: Sequence[SessionFrame], name: str
    ) -> Acquisition:
        """Acquisition mode for one recorded demonstration of skill ``name``
        (:func:`~ias_gym.assist.recognition.learn_demonstration`): stored in ``db``, the
        assistant's own library, when the recogniser calls it unknown or ``name``; then the
        recogniser knows it and the assistant completes it like a shipped skill, its motion
        from every stored session of it (and the pad keeping's pinches from every stored
        session). Call it between sessions.

        Raises:
            InputError: ``db`` is not the assistant's library, or the assistant has no skill
                knowledge to extend.
        """
        if self.library is None or db.path.resolve() != self.library.resolve():
            raise InputError(
                f"learn into the assistant's own library ({self.library}), not {db.path}"
            )
        if isinstance(self.recogniser, _NoRecogniser):
            raise InputError("an assistant without skill knowledge (recogniser 'none') learns none")
        result = learn_demonstration(db, self.recogniser, skill, frames, name)
        if result.stored_as is not None:
            self.motions = load_motions(self.library)
            if self.pads is not None:  # the new demonstration's pinch counts too
                self.pads.closing = pinch_closing(self.library)
        self.reset()
        return result

    def posterior(self) -> dict[str, float]:
        """The recogniser's posterior after the last :meth:`act`."""
        return dict(self._post)

    @property
    def completing(self) -> str | None:
        """The skill this session completes (None: no stop latched yet)."""
        return self._active

    @property
    def stopped(self) -> dict[str, float]:
        """Each skill's episode time [s] of the stop latched in this session."""
        return {k: c.stopped_at for k, c in self._fits.items() if c.stopped_at is not None}

    def _hold_pen(self, fit: Completion, height: float) -> None:
        """One step of the pen's hold (step 2's end): integrate the pen's height error
        against the skill's :attr:`~SkillMotion.goal_height` into the wrist flexion, and its
        axis' elevation error against the operator's tilt (the elevation when their motion
        started plus their fitted amplitude times the skill's
        :attr:`~SkillMotion.tilt_per_amplitude`) into the pronation."""
        assert fit.fit is not None  # a motion is done only once it is fitted
        motion, gain = fit.motion, self.params.sight_gain * self.dt
        a, _, t0 = fit.fit
        tilt_goal = float(np.interp(t0, self._times, self._tilts)) + a * motion.tilt_per_amplitude
        errors = [
            (WRIST_FLEXION, motion.goal_height - height, motion.rise_per_flexion),
            (WRIST_PRONATION, tilt_goal - self._tilts[-1], motion.tilt_per_pronation),
        ]
        for joint, error, per_rad in errors:
            if np.isfinite(error) and np.isfinite(per_rad) and per_rad != 0:
                step = gain * error / per_rad
                self._hold[joint] = np.clip(self._hold[joint] + step, -self.scale, self.scale)

    def _operator_theta(self, obs: FloatArray, layout: Mapping[str, slice]) -> FloatArray:
        if "upcoming_theta" in layout:
            return np.array(obs[layout["upcoming_theta"]], dtype=np.float64)
        return np.asarray(obs[layout["joint_angles"]], dtype=np.float64) - self._last_offset

    def act(self, obs: Any, layout: Mapping[str, slice] | None = None) -> FloatArray:
        """The action ``(10,)`` in [-1, 1] for the observation (``layout``: its parts;
        default the one given at construction).

        Raises:
            InputError: no layout, or one without the parts the assistant reads.
        """
        layout = layout if layout is not None else self.layout
        if layout is None:
            raise InputError("give the observation's layout (env.unwrapped.observation_layout)")
        obs = np.asarray(obs, dtype=np.float64)
        operator = self._operator_theta(obs, layout)
        now = float(obs[layout["time"]][0])  # the observation's time [s] ...
        t = now + self.dt  # ... and the step's the action acts on
        # a tremor is no motion of the skill's: what follows reads the targets without it
        offset = self.tremor.update(operator) if self.tremor is not None else np.zeros(N_JOINTS)
        theta = operator + offset
        # the recogniser sees what the hand is commanded: the operator's targets with the
        # assistant's last offset (a completed skill looks like the skill)
        frame = frame_from_observation(obs, layout, operator + self._last_offset)
        self._times.append(now)
        self._tilts.append(float(pen_elevation(obs[layout["pen_quat"]][None])[0]))
        post = dict(self.recogniser.update(frame))
        self._post = post
        self._posts.append(post)
        if self.completion and t >= LIFT_END:
            if self._theta0 is None:
                self._theta0 = theta.copy()
            refit = self._steps % REFIT_EVERY == 0
            for name, fit in self._fits.items():
                value = (theta - self._theta0)[fit.motion.joints]
                latched = fit.stopped_at is not None
                part = fit.update(t, value, refit)
                if not latched and fit.stopped_at is not None and fit.slow_since is not None:
                    # the skill as recognised when the operator began to slow down: what
                    # they meant; the first stop of the skill recognised first is completed
                    back = round((t - fit.slow_since) / self.dt)
                    before = self._posts[max(len(self._posts) - 1 - back, 0)]
                    if self._active is None and max(before, key=before.__getitem__) == name:
                        self._active, self._authority = name, before[name]
                if name == self._active:
                    offset[fit.motion.joints] += self._authority * part
                    if fit.motion_done:
                        self._hold_pen(fit, float(obs[layout["pen_position"]][2]))
            offset += self._authority * self._hold
        if self.pads is not None:
            offset += self.pads.update(obs[layout["feedback_torques"]], now)
        self._steps += 1
        out: FloatArray = np.clip(offset / self.scale, -1.0, 1.0)
        self._last_offset = out * self.scale
        return out


def make_assistant(
    db_path: str | Path | None = None,
    recogniser: str = "phase",
    params: AssistParams | str | Path | None = None,
    *,
    control_dt: float = 0.01,
    action_scale: float = 0.2,
    layout: Mapping[str, slice] | None = None,
    **switches: bool,
) -> ObservationAssistant:
    """An :class:`ObservationAssistant` on a skill library.

    Args:
        db_path: the skill database (default: the shipped library).
        recogniser: ``"phase"``, ``"dtw"`` or ``"none"`` (no skill knowledge).
        params: the thresholds, or a JSON file of them (default: the fitted ones).
        control_dt, action_scale: the env's (``env.unwrapped.config``).
        layout: the env's observation layout.
        **switches: ``completion``, ``tremor``, ``pads``, ``detection`` (ablations: False
            switches the part off; without ``detection`` the tremor canceller notches every
            operator, ``tremor_floor_rad`` 0).

    Raises:
        InputError: an unknown recogniser, a missing library or parameter file.
    """
    if recogniser not in RECOGNISERS:
        raise InputError(
            f"recogniser {recogniser!r} is not known; choose one of {', '.join(RECOGNISERS)}"
        )
    path = Path(db_path) if db_path is not None else shipped_skill_db()
    motions = load_motions(path)
    if recogniser == "none":
        rec: Any = _NoRecogniser()
    else:
        with SkillDB(path, readonly=True) as db:
            rec = make_recogniser(recogniser, db)
    if params is None or isinstance(params, str | Path):
        params = AssistParams.load(params if params is not None else PARAMS_PATH)
    closing = pinch_closing(path) if switches.pop("pads", True) else None
    if not switches.pop("detection", True):
        params = dataclasses.replace(params, tremor_floor_rad=0.0)
    return ObservationAssistant(
        motions,
        rec,
        params,
        control_dt=control_dt,
        action_scale=action_scale,
        layout=layout,
        closing=closing,
        library=path,
        **switches,
    )

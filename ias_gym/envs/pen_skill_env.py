"""IAS-PenSkill-v0: a robot hand performs a skill a person demonstrated through the glove.

The paper's Flow 2 (Proposition 1): a skill is stored as the time behaviour of the grip
transform G(t) - the object's trajectory and the internal forces - so that a hand of another
structure than the glove's can execute it. This env is the execution side: it takes the
skills as arrays (:class:`~ias_gym.envs.skill_reference.SkillReference`) and asks the hand to
move the pen along the reference while holding it with the person's grasp margin
(:mod:`ias_gym.grasp.grasp_margin`). Where the references come from is injected: a reader
(default :func:`ias_gym.skills.transfer.load_references`, which opens a skill database and
lives above the envs) turns ``skill_db`` and ``skill_ids`` into references for the hand.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar

import mujoco
import numpy as np

from ias_gym.envs.layout import ObservationParts
from ias_gym.envs.pen_hand_env import (
    FloatArray,
    PenHandConfig,
    PenHandEnv,
    PenReference,
)
from ias_gym.envs.skill_reference import ReferenceReader, SkillReference, default_reader
from ias_gym.errors import InputError
from ias_gym.grasp.grasp_margin import grasp_margin

#: Look-ahead of the observation's reference [control steps].
LOOK_AHEAD_STEPS: tuple[int, ...] = (5, 10)
#: Reward scales: position [m], rotation [rad], log margin ratio [-].
TRACK_POSITION_SCALE = 0.003
TRACK_ROTATION_SCALE = math.radians(3.0)
MARGIN_SCALE = 0.3
#: The measured margin in the observation is clipped to this [-] (inf: no squeeze needed).
MARGIN_CLIP = 10.0
#: Success tolerances of a reference that carries none and a config that sets none: RMS
#: position [m], RMS axis angle [rad], mean relative margin error [-] (inf: not checked).
DEFAULT_TOLERANCE = {"position": 0.003, "rotation": 0.05, "margin": math.inf}


@dataclasses.dataclass(frozen=True)
class PenSkillConfig(PenHandConfig):
    """PenSkill settings (units in the comments); the base fields are shared with PenRotate."""

    duration: float = 3.0  # episode length [s]; a shorter skill holds its last pose
    max_position_error: float = 0.015  # success: pen centre within this of nominal [m]
    drop_distance: float = 0.025  # pen centre this far from nominal = dropped [m]
    settle_time: float = 0.2  # the tracking errors ignore the first 0.2 s [s]
    # success: RMS position [m] and axis angle [rad] errors, mean relative margin error [-];
    # None: the skill reference's own tolerance, else the DEFAULT_TOLERANCE
    max_rms_position_error: float | None = None
    max_rms_rotation_error: float | None = None
    max_margin_error: float | None = None
    track_weight: float = 1.0  # [-]
    margin_weight: float = 0.5  # [-]

    def __post_init__(self) -> None:
        super().__post_init__()
        if not 0 <= self.settle_time < self.duration:
            raise ValueError(f"settle_time must be in [0, duration), got {self.settle_time}")
        for name in ("max_rms_position_error", "max_rms_rotation_error", "max_margin_error"):
            value = getattr(self, name)
            if value is not None and not value > 0:  # NaN fails too
                raise ValueError(f"{name} must be None or > 0, got {value}")


class PenSkillEnv(PenHandEnv):
    """Execute a person's skill (object trajectory and grasp margin) with a robot hand.

    ## Description
    ``IAS-PenSkill-v0``: the robot hand holds the pen and moves it along a skill a person
    demonstrated through the sensor glove (paper Flow 2, Proposition 1): the pen's
    displacement from where the person's grasp was established, scaled into this hand's
    workspace, while holding the pen with the person's grasp margin (the ratio of the
    squeeze applied to the least squeeze that keeps every contact in its friction cone,
    docs/transfer.md). Each reset draws one skill of the library.

    ## Action Space
    ``Box(-1, 1, (3 k,))``: joint torques of the hand's k fingers (abd, mcp, pip),
    normalised by the motors' limit (0.5 N m). Values outside [-1, 1] are clipped; NaN/inf
    raise ValueError.

    ## Observation Space
    ``Box(-inf, inf, (78,))`` for a four-finger hand, float64, paper frame, SI: the pen
    tasks' first 49 (joint angles and velocities, pen position, axis, velocity, angular
    velocity, tip forces, time fraction); then the reference pen position (3) and axis
    (3) now, 5 and 10 control steps ahead (12 more); the position error (3) and the axis
    error ``axis_ref x axis`` (3); the reference grasp margin and the measured one (clipped
    to 10) (2); the skill's progress (time / skill duration, 1) and its translation and
    rotation scales (2).

    By name: ``env.unwrapped.observation_layout[name]`` is the part's slice
    (:attr:`~ias_gym.envs.pen_hand_env.PenHandEnv.observation_parts` in order); k fingers:

    | name | size | content |
    |---|---|---|
    | ``joint_angles`` | 3k | hand joint angles [rad], the hand's joint order |
    | ``joint_velocities`` | 3k | their velocities [rad/s] |
    | ``pen_position`` | 3 | pen centre relative to nominal [m] |
    | ``pen_axis`` | 3 | unit vector along the pen's axis |
    | ``pen_velocity`` | 3 | pen centre velocity [m/s] |
    | ``pen_omega`` | 3 | pen angular velocity [rad/s] |
    | ``tip_forces`` | 3k | net force of each fingertip on the pen, 3 per finger [N] |
    | ``time_fraction`` | 1 | time since reset / episode duration |
    | ``reference_position`` | 3 | the reference pen position now [m] |
    | ``reference_axis`` | 3 | the reference axis now |
    | ``reference_position_ahead_5`` | 3 | the reference position 5 control steps ahead [m] |
    | ``reference_axis_ahead_5`` | 3 | the reference axis 5 control steps ahead |
    | ``reference_position_ahead_10`` | 3 | the reference position 10 control steps ahead [m] |
    | ``reference_axis_ahead_10`` | 3 | the reference axis 10 control steps ahead |
    | ``position_error`` | 3 | pen position minus the reference's [m] |
    | ``axis_error`` | 3 | ``axis_ref x axis`` |
    | ``grasp_margin_reference`` | 1 | the grasp margin to hold [-] |
    | ``grasp_margin`` | 1 | the measured grasp margin, clipped to 10 (0: a finger off) [-] |
    | ``progress`` | 1 | time / skill duration, at most 1 |
    | ``scale`` | 1 | the skill's translation scale [-] |
    | ``scale_rotation`` | 1 | its rotation scale [-] |

    ## Rewards
    Sum of named terms, each in ``info["reward_<name>"]``: ``track`` =
    exp(-(|e_p| / 3 mm)^2 - (e_R / 3 deg)^2) with e_p the position error and e_R the angle
    between the pen's axis and the reference's; ``margin`` = 0.5 x exp(-(log(m / m_ref) /
    0.3)^2) with m the measured grasp margin (0 while a finger is off); ``contact`` = 0.5 x
    fraction of tips touching; ``effort`` = -0.01 x mean(action^2).

    ## Starting State
    A stable grasp at the nominal pose, perturbed as in the other pen tasks (pen centre
    uniform within +-``pen_position_noise``, contacts at the hand's nominal positions
    +-``contact_noise``); the skill is drawn uniformly from the library with the env's
    ``np_random`` (``reset(options={"skill": i})`` picks skill i of the library).
    ``reset(options={"qpos": ..., "qvel": ...})`` starts from that exact MuJoCo state.

    ## Episode End
    ``info["is_success"]`` (at the last step): the pen was held (never dropped, no tip off
    for more than 20 ms, centre within ``max_position_error`` of nominal), ``tracked`` (RMS
    position error after ``settle_time`` below the position tolerance and RMS axis angle
    error below the rotation tolerance) and ``margin_kept`` (the mean relative margin
    error below the margin tolerance); ``info["tracked"]`` and ``info["margin_kept"]``
    tell which term failed. The tolerances (``env.unwrapped.tolerance()``) are the
    config's where it sets them, else the skill reference's own: for a stored skill, as
    close as another demonstration of the same person comes (fitted on repetitions of
    population persons, scaled like the reference: :mod:`ias_gym.skills.tolerance`),
    else 3 mm and 0.05 rad with the margin not checked. ``info`` also carries
    ``rms_position_error`` [m],
    ``rms_rotation_error`` [rad], ``margin`` (0 while a finger is off) and
    ``margin_reference`` [-], ``margin_error`` (mean relative error so far, -1 before the
    first sample), ``contact_forces`` [N] (k x 3: normal, t1, t2 of each fingertip) and
    ``internal_forces`` [N] (the measured c_h; 0 while a finger is off). Terminated when
    the pen is dropped (centre more than ``drop_distance`` from nominal); truncated by the
    time limit (``duration``) or a diverging simulation (``info["sim_unstable"]``).

    ## Arguments
    ``gym.make("IAS-PenSkill-v0", **kwargs)`` takes ``render_mode``, the skill library
    (``skill_db``: a skill database path, default the human skills shipped with the
    package; ``skill_ids``: which of its skills, default every successful glove skill;
    ``reader``: what reads them, default the skill database's reader
    :func:`ias_gym.skills.transfer.load_references`, which turns each skill into a
    reference for this hand) or ``references`` (a sequence of :class:`SkillReference`,
    built already), and these config fields:

    - ``hand`` [``"ias4f"``]: the robot hand.
    - ``control_dt`` [0.01 s], ``min_grasp_force`` [0.2 N], ``pen_position_noise``
      [0.001 m], ``contact_noise`` [0.001 m], ``penetration`` [3e-4 m]: as in the other pen
      tasks.
    - ``drop_distance`` [0.025 m], ``max_contact_gap`` [0.02 s], ``max_position_error``
      [0.015 m]: holding limits.
    - ``effort_weight`` [0.01], ``contact_weight`` [0.5], ``track_weight`` [1.0],
      ``margin_weight`` [0.5]: reward weights [-].
    - ``render_width`` [480 px], ``render_height`` [360 px], ``camera`` [``"front"``].
    - ``duration`` [3.0 s]: the episode; ``settle_time`` [0.2 s];
      ``max_rms_position_error`` [m], ``max_rms_rotation_error`` [rad] and
      ``max_margin_error`` [-] [``None``: the skill's own tolerances]: the tolerances of
      success.
    - Disturbances as in the other pen tasks: ``friction_scale``, ``mass_scale``,
      ``push_force``, ``push_duration``, ``force_noise``, ``joint_angle_noise``,
      ``joint_velocity_noise``, ``action_noise``, ``action_delay``,
      ``internal_force_step``.

    ## Version History
    - v0: initial release; success also asks for the margin kept, within tolerances of the
      persons' repeatability (before: 3 mm and 0.05 rad for every skill, no margin).
    """

    config_class: ClassVar[type[PenHandConfig]] = PenSkillConfig
    config: PenSkillConfig
    _episode_fields: ClassVar[tuple[str, ...]] = (
        *PenHandEnv._episode_fields,
        "_skill_index",
        "_sq_position",
        "_sq_rotation",
        "_sq_count",
        "_margin",
        "_margin_sum",
        "_margin_count",
        "_errors",
    )

    _skill_index: int
    _sq_position: float
    _sq_rotation: float
    _sq_count: int
    _margin: float
    _margin_sum: float
    _margin_count: int
    _errors: tuple[FloatArray, float, FloatArray]

    def __init__(
        self,
        render_mode: str | None = None,
        references: Sequence[SkillReference] = (),
        skill_db: str | Path | None = None,
        skill_ids: Sequence[int] | None = None,
        reader: ReferenceReader | None = None,
        **config: Any,
    ) -> None:
        """Build the task on a skill library: given, or read by ``reader``.

        Args:
            render_mode: ``None``, ``"human"``, ``"rgb_array"`` or ``"depth_array"``.
            references: the skill library (:class:`SkillReference` sampled at
                ``control_dt``); if empty, ``reader`` builds it.
            skill_db: where ``reader`` reads the skills (default reader: a skill database
                path; ``None``: the human skills shipped with the package).
            skill_ids: which of its skills (``None``: every successful glove skill).
            reader: ``reader(skill_db, skill_ids, hand, control_dt, duration)`` -> the
                references (default :func:`~ias_gym.envs.skill_reference.default_reader`:
                the skill database's).
            **config: fields of :class:`PenSkillConfig` to override.

        Raises:
            InputError: no references, or one sampled at another period than ``control_dt``.
        """
        if not references:
            cfg = PenSkillConfig(**config)
            read = reader if reader is not None else default_reader()
            references = read(skill_db, skill_ids, cfg.hand, cfg.control_dt, cfg.duration)
        self.skill_db = skill_db
        refs = tuple(references)
        if not refs:
            raise InputError("IAS-PenSkill-v0 needs at least one skill reference: none was read")
        dt = float(config.get("control_dt", PenSkillConfig.control_dt))
        for ref in refs:
            if not isinstance(ref, SkillReference):
                raise InputError(f"references must be SkillReference, got {type(ref).__name__}")
            if not math.isclose(ref.dt, dt):
                raise InputError(
                    f"skill reference {ref.skill_id} is sampled every {ref.dt} s, the env "
                    f"steps every {dt} s; build it for this control_dt"
                )
        self.references = refs
        self._skill_index = 0
        super().__init__(render_mode=render_mode, **config)

    # ------------------------------------------------------------------ the skill
    @property
    def skill(self) -> SkillReference:
        """The reference of this episode's skill."""
        return self.references[self._skill_index]

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[FloatArray, dict[str, Any]]:
        """Reset to a perturbed stable grasp and draw a skill.

        Args:
            seed: seeds ``self.np_random``.
            options: ``{"skill": i}`` executes skill i of the library; ``{"qpos": ...,
                "qvel": ...}`` starts from that exact MuJoCo state.

        Raises:
            InputError: ``options["skill"]`` is not an index of the library.
        """
        options = dict(options or {})
        if seed is not None:  # seed first so that the draw below uses the new generator
            super(PenHandEnv, self).reset(seed=seed)
        if "skill" in options:
            index = options.pop("skill")
            if not isinstance(index, (int, np.integer)) or not 0 <= index < len(self.references):
                raise InputError(
                    f"options skill={index!r} is not an index of the {len(self.references)} "
                    "skills of the library"
                )
            self._skill_index = int(index)
        else:
            self._skill_index = int(self.np_random.integers(len(self.references)))
        return super().reset(seed=None, options=options)

    def reference(self) -> PenReference:
        """The skill's pen motion now (what the expert tracks)."""
        return self.skill.at(self.time)

    def grasp_margin_reference(self) -> float:
        """The grasp margin the skill asks for now [-] (the expert scales its squeeze to it)."""
        return float(self.skill.margin[self.skill.index(self.time)])

    def grasp_margin(self) -> float:
        """The measured grasp margin now [-] (NaN while a finger is off; true Coulomb cones).

        From the measured contact intensities split by the grip transform (eqs. 5, 7):
        ``c_p = W+ W c`` and ``c_h = c - c_p``, with the pen's friction coefficient.
        """
        return self._margin

    def _measure_margin(self) -> float:
        p = self.physics
        contacts = p.fingertip_contacts()
        if not contacts.active.all():
            return math.nan
        W, _ = p.wrench_matrix(contacts)
        c = p.contact_intensities(contacts)
        c_p = np.linalg.lstsq(W, W @ c, rcond=None)[0]
        mu = float(self.model.geom_friction[p.pen_geom_id, 0])
        return grasp_margin(c_p, c - c_p, mu)

    # ------------------------------------------------------------------ task hooks
    def _task_update(self) -> None:
        if self._steps == 0:
            self._sq_position, self._sq_rotation, self._sq_count = 0.0, 0.0, 0
            self._margin_sum, self._margin_count = 0.0, 0
        ref = self.reference()
        s = self.state
        e_p = s.position - ref.position
        cross = np.cross(ref.axis, s.axis)
        angle = math.atan2(float(np.linalg.norm(cross)), float(ref.axis @ s.axis))
        self._errors = (e_p, angle, cross)
        self._margin = self._measure_margin()
        if self.time >= self.config.settle_time - 1e-9 and self._steps > 0:
            self._sq_position += float(e_p @ e_p)
            self._sq_rotation += angle * angle
            self._sq_count += 1
            target = self.grasp_margin_reference()
            if math.isfinite(self._margin):
                self._margin_sum += abs(min(self._margin, MARGIN_CLIP) - target) / target
                self._margin_count += 1

    def rms_errors(self) -> tuple[float, float]:
        """RMS position [m] and axis angle [rad] errors after ``settle_time`` so far."""
        if self._sq_count == 0:
            return 0.0, 0.0
        n = self._sq_count
        return math.sqrt(self._sq_position / n), math.sqrt(self._sq_rotation / n)

    def margin_error(self) -> float:
        """Mean relative error of the measured margin, ``|m - m_ref| / m_ref`` [-] (NaN: none)."""
        if self._margin_count == 0:
            return math.nan
        return self._margin_sum / self._margin_count

    def _reference_block(self, t: float) -> list[float]:
        skill = self.skill
        k = skill.index(t)
        return [*skill.position[k], *skill.axis[k]]

    def _task_observation(self) -> FloatArray:
        skill, t, dt = self.skill, self.time, self.config.control_dt
        e_p, _, cross = self._errors
        margin = self._margin if math.isfinite(self._margin) else 0.0
        values = self._reference_block(t)
        for ahead in LOOK_AHEAD_STEPS:
            values += self._reference_block(t + ahead * dt)
        values += [*e_p, *cross, self.grasp_margin_reference(), min(margin, MARGIN_CLIP)]
        values += [min(t / max(skill.duration, dt), 1.0), skill.scale, skill.scale_rotation]
        return np.array(values)

    def _task_observation_parts(self) -> ObservationParts:
        ahead = [
            part
            for k in LOOK_AHEAD_STEPS
            for part in ((f"reference_position_ahead_{k}", 3), (f"reference_axis_ahead_{k}", 3))
        ]
        return (
            ("reference_position", 3),
            ("reference_axis", 3),
            *ahead,
            ("position_error", 3),
            ("axis_error", 3),
            ("grasp_margin_reference", 1),
            ("grasp_margin", 1),
            ("progress", 1),
            ("scale", 1),
            ("scale_rotation", 1),
        )

    def _task_reward(self) -> dict[str, float]:
        cfg = self.config
        e_p, angle, _ = self._errors
        track = math.exp(
            -float(e_p @ e_p) / TRACK_POSITION_SCALE**2 - (angle / TRACK_ROTATION_SCALE) ** 2
        )
        margin = 0.0
        if math.isfinite(self._margin) and self._margin > 0:
            ratio = math.log(min(self._margin, MARGIN_CLIP) / self.grasp_margin_reference())
            margin = math.exp(-((ratio / MARGIN_SCALE) ** 2))
        return {"track": cfg.track_weight * track, "margin": cfg.margin_weight * margin}

    def tolerance(self) -> dict[str, float]:
        """This episode's success tolerances: ``position`` [m], ``rotation`` [rad] and
        ``margin`` [-], each the config's if set, else the skill's, else the default."""
        cfg, skill = self.config, self.skill
        chosen = {
            "position": (cfg.max_rms_position_error, skill.tolerance_position),
            "rotation": (cfg.max_rms_rotation_error, skill.tolerance_rotation),
            "margin": (cfg.max_margin_error, skill.tolerance_margin),
        }
        return {
            key: next((v for v in values if v is not None), DEFAULT_TOLERANCE[key])
            for key, values in chosen.items()
        }

    def success_terms(self) -> dict[str, bool]:
        """Whether the run so far ``tracked`` the motion (RMS position and axis errors within
        the tolerance) and kept the margin (``margin_kept``: its mean relative error within
        the tolerance; a run with no margin sample keeps it only if it is not checked)."""
        pos, rot = self.rms_errors()
        tol = self.tolerance()
        error = self.margin_error()
        kept = math.isinf(tol["margin"]) or (math.isfinite(error) and error < tol["margin"])
        return {
            "tracked": bool(pos < tol["position"] and rot < tol["rotation"]),
            "margin_kept": bool(kept),
        }

    def _task_success(self) -> bool:
        return all(self.success_terms().values())

    def episode_metrics(self, info: dict[str, Any]) -> dict[str, float]:
        """Error metrics of a finished episode from its last ``info`` (SI units)."""
        return {
            "rms_position_error": float(info["rms_position_error"]),
            "rms_rotation_error": float(info["rms_rotation_error"]),
            "margin_error": float(info["margin_error"]) if info["margin_error"] >= 0 else math.nan,
            "max_position_error": float(info["max_position_error"]),
        }

    def _task_info(self) -> dict[str, Any]:
        pos, rot = self.rms_errors()
        contacts = self.physics.fingertip_contacts()
        c = self.physics.contact_intensities(contacts)
        # No NaN in info (a NaN never equals itself, and a rollout's infos are compared):
        # while a finger is off the internal forces and the margin read 0, and the margin
        # error -1 until the first sample after settle_time.
        if contacts.active.all():
            W, _ = self.physics.wrench_matrix(contacts)
            c_h = c - np.linalg.lstsq(W, W @ c, rcond=None)[0]
        else:
            c_h = np.zeros_like(c)
        margin_error = self.margin_error()
        return {
            "skill_index": self._skill_index,
            "skill_id": self.skill.skill_id,
            "position_error": float(np.linalg.norm(self._errors[0])),
            "rotation_error": self._errors[1],
            "rms_position_error": pos,
            "rms_rotation_error": rot,
            "margin": self._margin if math.isfinite(self._margin) else 0.0,
            "margin_reference": self.grasp_margin_reference(),
            "margin_error": margin_error if math.isfinite(margin_error) else -1.0,
            **self.success_terms(),
            "contact_forces": c.reshape(-1, 3),
            "internal_forces": c_h,
        }

    # ------------------------------------------------------------------ pickling
    def __getstate__(self) -> dict[str, Any]:
        """Pickle as the base does, plus the skill library."""
        state = super().__getstate__()
        state["references"], state["skill_db"] = self.references, self.skill_db
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Rebuild the env from its configuration and library, then restore the state."""
        PenSkillEnv.__init__(
            self,
            render_mode=state["render_mode"],
            references=state["references"],
            skill_db=state["skill_db"],
            **state["config"],
        )
        spec = mujoco.mjtState.mjSTATE_INTEGRATION
        mujoco.mj_setState(self.model, self.data, state["mj_state"], spec)
        mujoco.mj_forward(self.model, self.data)
        for key, value in state["episode"].items():
            setattr(self, key, value)
        self._np_random = state["np_random"]
        self._measure()

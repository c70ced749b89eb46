"""Skill transfer: a stored skill (paper Flow 2, Proposition 1) as a reference for another hand.

A skill is stored as the time behaviour of the grip transform G(t): the object's trajectory
and the wrench intensities ``c = c_p + c_h`` (eqs. 3-10). What a hand of another structure
can reuse is not the glove's joint angles but

- the object's motion **relative to its grasp frame**: the pen's displacement from its pose
  at the skill's own start (the instant the grasp is established), expressed in a frame
  that keeps gravity vertical and turns the pen's initial heading onto the hand's x axis;
- scaled into the target hand's **workspace** (:class:`HandWorkspace`): translations by
  ``scale = min(1, reach / largest displacement)``, rotations by ``scale_rotation =
  min(1, largest tilt / largest rotation)``. Two scales, not one: a hand geometrically
  similar to the person's but k times smaller moves the object k times less far but
  through the same angles, so angles are left alone unless the hand cannot reach them;
- resampled to the env's control period and differentiated by a Savitzky-Golay filter
  (scipy; the glove's noise would otherwise dominate the second differences);
- with the **external wrench** it implies, ``w = [m a - m g; I alpha + omega x I omega]``
  (eq. 33 plus the weight, as :func:`ias_gym.baselines.law.object_wrench`), for the target
  hand's pen;
- and the **grasp margin** ``m(t)`` of the demonstration
  (:mod:`ias_gym.grasp.grasp_margin`): the person's squeeze over the least squeeze that keeps
  the contacts in their cones. The target hand solves its own internal forces for its own
  contacts and scales them to the same margin (the controller's hook,
  ``grasp_margin_reference``);
- and the **tolerances** of its success test: as close as another demonstration of the
  same person comes (:mod:`ias_gym.skills.tolerance`), scaled like the reference.

:func:`load_references` is the reader that ``IAS-PenSkill-v0``
(:class:`~ias_gym.envs.pen_skill_env.PenSkillEnv`) is given by default: it reads the skills
from a database (default: the human skills shipped with the package) and builds their
references for the env's hand. The math, with the equations: docs/transfer.md.
"""

from __future__ import annotations

import importlib.resources
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.signal import savgol_filter

from ias_gym.envs.pen_skill_env import PenSkillEnv
from ias_gym.envs.skill_reference import SkillReference
from ias_gym.errors import (
    InputError,
    SkillTransferError,
)
from ias_gym.grasp.grasp_margin import margin_series
from ias_gym.rollout import rollout
from ias_gym.sim import hands
from ias_gym.sim.pen import rpy_to_matrix
from ias_gym.sim.scene_constants import glove_pad_friction
from ias_gym.skills.db import SkillDB
from ias_gym.skills.glove_session import motion_window
from ias_gym.skills.skill import Skill
from ias_gym.skills.tolerance import Tolerance, skill_tolerance

FloatArray = NDArray[np.float64]

#: The human-skill library shipped in ``ias_gym.assets``.
SHIPPED_DB = "human_skills.db"
#: The margin reference is kept in this range [-]: below 1 would ask the robot to slip,
#: and ``inf`` (no squeeze needed) leaves the hand its own least squeeze.
MARGIN_RANGE = (1.0, 10.0)
#: Savitzky-Golay filter of the resampled trajectory: window [samples] and polynomial order.
SMOOTH_WINDOW = 11
SMOOTH_ORDER = 3


@dataclass(frozen=True)
class HandWorkspace:
    """The part of a hand's workspace a transferred skill is scaled into.

    Attributes:
        reach: how far the hand moves the held pen's centre [m].
        tilt: the largest rotation of the pen's axis the expert handles [rad].
    """

    reach: float
    tilt: float


#: The held pen's centre moves at most this fraction of the tips' reach along the pen: the
#: reach is measured with the pen at rest, and the tips must still hold the pen at the far
#: end of a translation, tilted (measured on both hands: docs/transfer.md).
TRANSLATION_SHARE = 0.3


def hand_names() -> list[str]:
    """The robot hands a skill can be transferred to (:data:`ias_gym.sim.hands.HANDS`)."""
    return list(hands.hand_names())


def hand_workspace(hand: str) -> HandWorkspace:
    """The workspace of a hand, from its ``HandSpec``: the pen centre moves up to
    :data:`TRANSLATION_SHARE` of the tips' reach, its axis turns up to the largest tilt the
    expert tracks.

    Raises:
        InputError: an unknown hand (the message lists the known ones).
    """
    spec = hands.get_hand(hand)
    return HandWorkspace(reach=TRANSLATION_SHARE * spec.reach, tilt=spec.max_tilt)


def skill_start_index(skill: Skill) -> int:
    """The sample where the skill's own motion starts: the grasp is established.

    A glove session stores where its skill's motion starts (:func:`motion_window`); for
    any other record it is the first sample from which every finger touches the object and
    the internal forces are defined.

    Raises:
        SkillTransferError: the fingers never hold the object together.
    """
    model = skill.model
    window = motion_window(skill)
    if window is not None:
        return int(np.searchsorted(model.time, window[0] - 1e-9))
    held = model.touching.all(axis=1) & np.all(np.isfinite(model.c_h), axis=1)
    if not held.any():
        raise SkillTransferError(
            f"skill {skill.id} ({skill.name}) has no sample where every finger touches the "
            "object: there is no grasp to transfer"
        )
    return int(np.argmax(held))


def demonstrated_margin(skill: Skill, mu: float | None = None) -> FloatArray:
    """``m(t)`` of the demonstration, one value per sample (NaN where a contact is missing).

    Args:
        skill: a stored skill with its model's ``c`` and ``c_h``.
        mu: the object's friction coefficient [-] (default: the glove world's pen contacts,
            :func:`~ias_gym.sim.scene_constants.glove_pad_friction`); soft-finger skills (4
            intensities per finger) also bound the torsion with the glove pads' torsional
            friction.
    """
    glove_mu, glove_torsion = glove_pad_friction()
    m = skill.model
    k = m.touching.shape[1]
    per = m.c.shape[1] // k
    mu_t = glove_torsion if per == 4 else 0.0
    return margin_series(m.c_p, m.c_h, m.touching, glove_mu if mu is None else mu, mu_t)


def _axis_angles(rpy: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Tilt (elevation, about the lateral axis) and turn (heading, about vertical) [rad]."""
    axes = np.array([rpy_to_matrix(r)[:, 0] for r in rpy])
    x, y, z = axes.T
    return np.arctan2(y, np.hypot(x, z)), np.unwrap(np.arctan2(-z, x))


def _derivatives(values: FloatArray, dt: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Smoothed values and their first two derivatives along axis 0 (Savitzky-Golay)."""
    window = min(SMOOTH_WINDOW, len(values) - (1 - len(values) % 2))
    if window <= SMOOTH_ORDER:
        zero = np.zeros_like(values)
        return values, zero, zero
    out = [
        savgol_filter(values, window, SMOOTH_ORDER, deriv=d, delta=dt, axis=0, mode="interp")
        for d in (0, 1, 2)
    ]
    return out[0], out[1], out[2]


def transfer_reference(
    skill: Skill,
    hand: str = "ias4f",
    control_dt: float = 0.01,
    duration: float | None = None,
    mu: float | None = None,
    workspace: HandWorkspace | None = None,
    tolerances: dict[str, Tolerance] | None = None,
) -> SkillReference:
    """The reference a hand executes for a stored skill (module docstring).

    Args:
        skill: the stored skill (e.g. a glove session).
        hand: the target hand's name (its workspace, unless ``workspace`` is given).
        control_dt: the target env's control period [s].
        duration: cut the reference after this long [s] (default: the whole skill).
        mu: the demonstration's friction coefficient [-] (for its grasp margin; default:
            the glove world's, as :func:`demonstrated_margin`).
        workspace: overrides the hand's workspace.
        tolerances: the success tolerances by skill class (default: the shipped ones,
            :func:`ias_gym.skills.tolerance.load_tolerances`).

    Returns:
        The :class:`SkillReference` on the grid ``0, dt, 2 dt, ...`` after the skill's start.

    Raises:
        SkillTransferError: the skill has no grasp, or fewer than 2 samples after it.
        InputError: an unknown hand.
    """
    ws = workspace or hand_workspace(hand)
    model = skill.model
    start = skill_start_index(skill)
    t_rel = model.time[start:] - model.time[start]
    end = t_rel[-1] if duration is None else min(t_rel[-1], duration)
    grid = np.arange(0.0, end + 1e-9, control_dt)
    if len(grid) < 2:
        raise SkillTransferError(
            f"skill {skill.id} ({skill.name}) lasts {t_rel[-1]:.3f} s after its grasp; a "
            f"reference needs at least two control periods of {control_dt} s"
        )

    def resample(values: FloatArray) -> FloatArray:
        return np.stack([np.interp(grid, t_rel, v) for v in values.T], axis=1)

    tilt, turn = _axis_angles(model.pen_rpy[start:])
    tilt, turn = tilt - tilt[0], turn - turn[0]
    # the displacement in the heading frame of the start: gravity vertical, pen along +x
    b0 = float(_axis_angles(model.pen_rpy[start : start + 1])[1][0])
    c, s = math.cos(b0), math.sin(b0)
    heading_inverse = np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])  # R_y(-b0)
    displacement = (model.pen_position[start:] - model.pen_position[start]) @ heading_inverse.T

    largest_move = float(np.max(np.linalg.norm(displacement, axis=1)))
    largest_turn = float(np.max(np.hypot(tilt, turn)))
    scale = min(1.0, ws.reach / largest_move) if largest_move > 0 else 1.0
    scale_rot = min(1.0, ws.tilt / largest_turn) if largest_turn > 0 else 1.0

    position, velocity, acceleration = _derivatives(scale * resample(displacement), control_dt)
    angles = scale_rot * resample(np.stack([tilt, turn], axis=1))
    a, b = angles[:, 0], angles[:, 1]
    axis = np.stack([np.cos(a) * np.cos(b), np.sin(a), -np.cos(a) * np.sin(b)], axis=1)
    _, axis_rate, axis_acc = _derivatives(axis, control_dt)
    # the pen's roll about itself is free: omega is the axis' rate of turn, omega = u x u'
    # (and alpha = u x u'', as u' x u' = 0)
    omega = np.cross(axis, axis_rate)
    alpha = np.cross(axis, axis_acc)

    margin = demonstrated_margin(skill, mu)[start:]
    defined = np.isfinite(margin) | np.isposinf(margin)
    if not defined.any():
        raise SkillTransferError(
            f"skill {skill.id} ({skill.name}) has no sample with a grasp margin (no "
            "contacts with internal forces)"
        )
    times = t_rel[defined]
    values = np.clip(margin[defined], *MARGIN_RANGE)
    nearest = np.clip(np.searchsorted(times, grid), 0, len(times) - 1)
    margin_ref = values[nearest]
    tolerance = skill_tolerance(skill.name, tolerances).scaled(scale, scale_rot)
    return SkillReference(
        dt=control_dt,
        position=position,
        velocity=velocity,
        acceleration=acceleration,
        axis=axis,
        omega=omega,
        alpha=alpha,
        margin=margin_ref,
        skill_id=-1 if skill.id is None else int(skill.id),
        name=skill.name,
        person=skill.person_id or "",
        scale=scale,
        scale_rotation=scale_rot,
        tolerance_rotation=tolerance.rotation,
        tolerance_position=tolerance.position,
        tolerance_margin=tolerance.margin,
    )


def implied_wrench(
    reference: SkillReference,
    mass: float,
    inertia: FloatArray,
    gravity: Sequence[float] = (0.0, -9.81, 0.0),
) -> FloatArray:
    """The net contact wrench the reference implies, ``[m a - m g; I alpha + omega x I omega]``.

    Eq. (33) plus the weight (eq. 18), as the controller's ``object_wrench``; ``c_p = W+ w``.

    Args:
        reference: the skill's reference.
        mass: the target hand's object mass [kg].
        inertia: ``(3, 3)`` its inertia about the centre of mass [kg m^2], paper frame.
        gravity: [m/s^2], paper frame.

    Returns:
        ``(T, 6)`` [N, N m].
    """
    g = np.asarray(gravity, dtype=float)
    force = mass * reference.acceleration - mass * g
    i_omega = reference.omega @ np.asarray(inertia).T
    moment = reference.alpha @ np.asarray(inertia).T + np.cross(reference.omega, i_omega)
    result: FloatArray = np.concatenate([force, moment], axis=1)
    return result


def shipped_skill_db() -> Path:
    """The human-skill database shipped with the package (glove sessions of several people)."""
    with importlib.resources.as_file(
        importlib.resources.files("ias_gym.assets") / SHIPPED_DB
    ) as path:
        return Path(path)


def load_references(
    skill_db: str | Path | None = None,
    skill_ids: Sequence[int] | None = None,
    hand: str = "ias4f",
    control_dt: float = 0.01,
    duration: float | None = None,
) -> list[SkillReference]:
    """Read skills from a database and build their references for a hand.

    Args:
        skill_db: the database (default :func:`shipped_skill_db`); opened read-only, every
            skill's arrays checked against their checksums.
        skill_ids: which skills (default: every successful glove skill there).
        hand, control_dt, duration: as :func:`transfer_reference`.

    Raises:
        InputError: the database is missing, an id is unknown, or none can be transferred.
    """
    path = Path(skill_db) if skill_db is not None else shipped_skill_db()
    if not path.is_file():
        raise InputError(f"skill database {path} does not exist")
    refs = []
    with SkillDB(path, readonly=True) as db:
        if skill_ids is None:
            ids = [s.id for s in db.list_skills(success=True) if s.person_id]
        else:
            ids = [int(i) for i in skill_ids]
        known = {s.id for s in db.list_skills()}
        unknown = sorted(set(ids) - known)
        if unknown:
            raise InputError(f"no skills with ids {unknown} in {path}; ids there: {sorted(known)}")
        for skill_id in ids:
            refs.append(transfer_reference(db.get(skill_id), hand, control_dt, duration))
    if not refs:
        raise InputError(f"no transferable skills in {path}")
    return refs


#: Methods of executing a transferred skill: the grip-transform expert (Theorem 1 on the
#: skill's reference and margin) and the kinematic baseline.
METHODS: tuple[str, ...] = ("gt", "kinematic")


@dataclass
class TransferRun:
    """One execution of a transferred skill by one hand, with its traces.

    Attributes:
        hand, method: which hand, which method (``gt`` or ``kinematic``).
        skill_id: the skill's id in its database; person, name: its provenance.
        success: the env's ``is_success``: ``held``, ``tracked`` and ``margin_kept``.
        held: the pen held for the whole episode; tracked: RMS rotation and position
            errors within the reference's tolerances; margin_kept: the margin error within
            its tolerance.
        held_s: how long the pen was held [s] (the episode's length unless dropped; the
            RMS errors are over that time).
        rot_rms_deg: RMS angle between the pen's axis and the reference's [deg].
        pos_rms_mm: RMS distance of the pen's centre from the reference's [mm].
        margin_err_rel: mean ``|m - m_ref| / m_ref`` of the grasp margin [-].
        scale, scale_rotation: the reference's translation and rotation scales [-].
        tolerance: the success test's ``rot_rms_deg``, ``pos_rms_mm``, ``margin_err_rel``.
        time: ``(T,)`` [s]; position, reference_position: ``(T, 3)`` [m]; axis,
        reference_axis: ``(T, 3)``; margin, margin_reference: ``(T,)`` [-];
        internal_forces: ``(T, n)`` measured ``c_h`` [N]; contact_forces: ``(T, k, 3)`` [N].
    """

    hand: str
    method: str
    skill_id: int
    person: str
    name: str
    success: bool
    held: bool
    tracked: bool
    margin_kept: bool
    held_s: float
    rot_rms_deg: float
    pos_rms_mm: float
    margin_err_rel: float
    scale: float
    scale_rotation: float
    tolerance: dict[str, float]
    time: FloatArray
    position: FloatArray
    reference_position: FloatArray
    axis: FloatArray
    reference_axis: FloatArray
    margin: FloatArray
    margin_reference: FloatArray
    internal_forces: FloatArray
    contact_forces: FloatArray

    def to_json(self) -> dict[str, Any]:
        """The metrics as a JSON-ready dict (units in the keys; NaN becomes ``None``)."""

        def number(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        return {
            "hand": self.hand,
            "method": self.method,
            "skill_id": self.skill_id,
            "person": self.person,
            "skill": self.name,
            "success": self.success,
            "held": self.held,
            "tracked": self.tracked,
            "margin_kept": self.margin_kept,
            "held_s": self.held_s,
            "rot_rms_deg": number(self.rot_rms_deg),
            "pos_rms_mm": number(self.pos_rms_mm),
            "margin_err_rel": number(self.margin_err_rel),
            "scale": self.scale,
            "scale_rot": self.scale_rotation,
            "tolerance": {k: number(v) for k, v in self.tolerance.items()},
        }


class _Executing:
    """A policy that acts on another reference than the one its env judges it by (the
    weak executions that check the success test: a still pen, a constant margin)."""

    def __init__(self, policy: Any, env: PenSkillEnv, executed: SkillReference) -> None:
        self.policy, self.env, self.executed = policy, env, executed

    def predict(self, observation: Any, *args: Any, **kwargs: Any) -> Any:
        judged = self.env.references
        self.env.references = (self.executed,)
        try:
            return self.policy.predict(observation, *args, **kwargs)
        finally:
            self.env.references = judged


def run_transfer(
    reference: SkillReference,
    hand: str = "ias4f",
    method: str = "gt",
    seed: int = 0,
    render: bool = False,
    executed: SkillReference | None = None,
    gains: Any = None,
    reset_options: dict[str, Any] | None = None,
    **config: Any,
) -> tuple[TransferRun, list[NDArray[Any]]]:
    """Execute a transferred skill on a hand and measure it.

    Args:
        reference: from :func:`transfer_reference` for this hand.
        hand: the hand.
        method: ``"gt"`` (the grip-transform expert: Theorem 1 with the skill's margin) or
            ``"kinematic"`` (:class:`~ias_gym.baselines.kinematic.KinematicPolicy`).
        seed: the reset seed.
        render: also return ``rgb_array`` frames (every other step: 50 fps).
        executed: the policy acts on this reference instead (same length of episode),
            while the run is still judged against ``reference``: a deliberately weak
            execution (e.g. the pen held still) that the success test must fail.
        gains: the method's gains: the expert's
            :class:`~ias_gym.baselines.grip_transform_control.ControllerGains` or the
            kinematic baseline's :class:`~ias_gym.baselines.kinematic.KinematicGains`
            (default: its own).
        reset_options: further options of the reset (e.g. an exact start, ``qpos`` and
            ``qvel``); the skill is always the reference.
        **config: further :class:`PenSkillConfig` fields.

    Returns:
        ``(run, frames)``; ``frames`` is empty unless ``render``.

    Raises:
        InputError: an unknown method.
    """
    # the policies: imported here, so that reading references does not load them
    from ias_gym.baselines.expert import ExpertPolicy
    from ias_gym.baselines.kinematic import KinematicPolicy

    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; methods: {list(METHODS)}")
    env = PenSkillEnv(
        render_mode="rgb_array" if render else None, references=[reference], hand=hand, **config
    )
    try:
        policy: Any = ExpertPolicy(env, gains) if method == "gt" else KinematicPolicy(env, gains)
        if executed is not None:
            policy = _Executing(policy, env, executed)
        rows: dict[str, list[Any]] = {
            k: [] for k in ("t", "p", "pr", "a", "ar", "m", "mr", "ch", "cf")
        }
        frames: list[NDArray[Any]] = []

        def sample(_env: Any, *args: Any) -> None:  # after the reset and every step
            info = args[-1]
            ref = env.reference()
            rows["t"].append(env.time)
            rows["p"].append(env.state.position.copy())
            rows["pr"].append(ref.position)
            rows["a"].append(env.state.axis.copy())
            rows["ar"].append(ref.axis)
            rows["m"].append(env.grasp_margin())
            rows["mr"].append(info["margin_reference"])
            rows["ch"].append(info["internal_forces"])
            rows["cf"].append(info["contact_forces"])
            if render and env._steps % 2 == 0:
                frame = env.render()
                if frame is not None:
                    frames.append(frame)

        trajectory = rollout(
            env,
            policy,
            seed,
            reset_options={**(reset_options or {}), "skill": 0},
            keep_observations=False,
            keep_infos=False,
            on_reset=sample,
            on_step=sample,
        )
        held = env.held()
        tolerance = env.tolerance()
    finally:
        env.close()
    info = trajectory.final_info
    run = TransferRun(
        hand=hand,
        method=method,
        skill_id=reference.skill_id,
        person=reference.person,
        name=reference.name,
        success=bool(info["is_success"]),
        held=held,
        tracked=bool(info["tracked"]),
        margin_kept=bool(info["margin_kept"]),
        held_s=round(float(rows["t"][-1]), 6),  # MuJoCo's clock sums its steps: 2.9999999999998
        rot_rms_deg=math.degrees(info["rms_rotation_error"]),
        pos_rms_mm=1000.0 * info["rms_position_error"],
        margin_err_rel=env.margin_error(),
        scale=reference.scale,
        scale_rotation=reference.scale_rotation,
        tolerance={
            "rot_rms_deg": math.degrees(tolerance["rotation"]),
            "pos_rms_mm": 1000.0 * tolerance["position"],
            "margin_err_rel": tolerance["margin"],
        },
        time=np.array(rows["t"]),
        position=np.array(rows["p"]),
        reference_position=np.array(rows["pr"]),
        axis=np.array(rows["a"]),
        reference_axis=np.array(rows["ar"]),
        margin=np.array(rows["m"], dtype=float),
        margin_reference=np.array(rows["mr"], dtype=float),
        internal_forces=np.array(rows["ch"], dtype=float),
        contact_forces=np.array(rows["cf"], dtype=float),
    )
    return run, frames

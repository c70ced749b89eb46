"""Skill transfer: a stored skill (paper Flow 2, Proposition 1) as a reference for another hand.

A skill is stored as the time behaviour of the grip transform G(t): the object's trajectory
and the wrench intensities ``c = c_p + c_h`` (eqs. 3-10). What a hand of another structure
can reuse is not the glove's joint angles but

- the object's motion **relative to its grasp frame**: the pen's displacement from its pose
  at the skill's own start (the instant the grasp is established), expressed in a frame
  that keeps gravity vertical and turns the pen's initial heading onto the hand's x axis;
- scaled into the target hand's **workspace** (:class:`HandWorkspace`, measured per hand):
  the rotation by ``scale_rotation`` (its largest turn within the hand's tilt, its fastest
  within the hand's tilt rate), the translation by one ``scale`` (within the reach at that
  tilt along every axis and diagonal, within the hand's speed, and never above
  ``scale_rotation``: a turn keeps the person's pivot). Two scales, not one: a hand k times
  smaller than the person's moves the object k times less far through the same angles;
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
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.signal import savgol_filter

from ias_gym.envs.skill_reference import SkillReference
from ias_gym.errors import (
    InputError,
    SkillTransferError,
)
from ias_gym.grasp.grasp_margin import margin_series
from ias_gym.sim.pen import rpy_to_matrix
from ias_gym.sim.scene_constants import glove_pad_friction
from ias_gym.skills.db import SkillDB
from ias_gym.skills.glove_session import motion_window
from ias_gym.skills.skill import Skill
from ias_gym.skills.tolerance import Tolerance, skill_tolerance
from ias_gym.skills.workspace import (
    HandWorkspace,
    hand_workspace,
    workspace_scales,
)

FloatArray = NDArray[np.float64]

#: The human-skill library shipped in ``ias_gym.assets``.
SHIPPED_DB = "human_skills.db"
#: The margin reference is kept in this range [-]: below 1 would ask the robot to slip,
#: and ``inf`` (no squeeze needed) leaves the hand its own least squeeze.
MARGIN_RANGE = (1.0, 10.0)
#: Savitzky-Golay filter of the resampled trajectory: window [samples] and polynomial order.
SMOOTH_WINDOW = 11
SMOOTH_ORDER = 3


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
    m = skill.model
    glove_mu, mu_t = demonstration_friction(skill)
    return margin_series(m.c_p, m.c_h, m.touching, glove_mu if mu is None else mu, mu_t)


def demonstration_friction(skill: Skill) -> tuple[float, float]:
    """``(mu, mu_torsion)`` the demonstration's margins are measured with: the glove world's
    pen contacts (:func:`~ias_gym.sim.scene_constants.glove_pad_friction`), the torsional
    part only for soft-finger records (4 intensities per contact) [-], [m]."""
    glove_mu, glove_torsion = glove_pad_friction()
    m = skill.model
    per = m.c.shape[1] // m.touching.shape[1]
    return glove_mu, glove_torsion if per == 4 else 0.0


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


def motion_reference(
    position: FloatArray,
    angles: FloatArray,
    margin: FloatArray,
    control_dt: float,
    **fields: Any,
) -> SkillReference:
    """A :class:`SkillReference` from a pen motion sampled every ``control_dt``.

    The position is smoothed and differentiated by the Savitzky-Golay filter
    (:data:`SMOOTH_WINDOW`, :data:`SMOOTH_ORDER`); the axis is built from the two angles
    and its rates give the angular velocity and acceleration (the pen's roll is free).

    Args:
        position: ``(T, 3)`` pen centre relative to its start, already scaled [m].
        angles: ``(T, 2)`` tilt (elevation) and turn (heading) of the axis, already
            scaled [rad].
        margin: ``(T,)`` grasp margin to hold [-].
        control_dt: the sample period [s].
        **fields: the reference's other fields (name, person, scales, tolerances).
    """
    position, velocity, acceleration = _derivatives(position, control_dt)
    a, b = angles[:, 0], angles[:, 1]
    axis = np.stack([np.cos(a) * np.cos(b), np.sin(a), -np.cos(a) * np.sin(b)], axis=1)
    _, axis_rate, axis_acc = _derivatives(axis, control_dt)
    # the pen's roll about itself is free: omega is the axis' rate of turn, omega = u x u'
    # (and alpha = u x u'', as u' x u' = 0)
    return SkillReference(
        dt=control_dt,
        position=position,
        velocity=velocity,
        acceleration=acceleration,
        axis=axis,
        omega=np.cross(axis, axis_rate),
        alpha=np.cross(axis, axis_acc),
        margin=margin,
        **fields,
    )


def skill_motion(skill: Skill) -> tuple[FloatArray, FloatArray]:
    """The pen's motion from the skill's start (:func:`skill_start_index`), unscaled.

    Returns:
        ``(displacement, angles)``: ``(T, 3)`` the centre's displacement [m] in the frame
        of the start's heading (x along the pen's initial heading, y up, z lateral: gravity
        vertical), and ``(T, 2)`` the axis' tilt (elevation) and turn (heading) from the
        start [rad], one row per stored sample from the start on.

    Raises:
        SkillTransferError: the skill has no grasp.
    """
    model = skill.model
    start = skill_start_index(skill)
    tilt, turn = _axis_angles(model.pen_rpy[start:])
    b0 = float(turn[0])
    c, s = math.cos(b0), math.sin(b0)
    heading_inverse = np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])  # R_y(-b0)
    displacement = (model.pen_position[start:] - model.pen_position[start]) @ heading_inverse.T
    return displacement, np.stack([tilt - tilt[0], turn - turn[0]], axis=1)


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

    displacement, turns = skill_motion(skill)
    largest_turn = float(np.max(np.hypot(turns[:, 0], turns[:, 1])))
    _, turn_rates, _ = _derivatives(resample(turns), control_dt)
    largest_rate = float(np.max(np.hypot(turn_rates[:, 0], turn_rates[:, 1])))
    _, velocity, _ = _derivatives(resample(displacement), control_dt)
    fastest = float(np.max(np.linalg.norm(velocity, axis=1)))
    scale, scale_rot = workspace_scales(ws, displacement, largest_turn, largest_rate, fastest)
    if scale <= 0 and np.any(displacement):
        raise SkillTransferError(
            f"skill {skill.id} ({skill.name}): hand {hand} carries the pen nowhere along its "
            "motion at any tilt it was probed at"
        )

    position = scale * resample(displacement)
    angles = scale_rot * resample(turns)

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
    return motion_reference(
        position,
        angles,
        margin_ref,
        control_dt,
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

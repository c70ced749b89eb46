"""Glove sessions as skills: the skill model of ``IAS-GloveGrasp-v0`` (paper secs. 2-3).

In the skill-acquisition loop (Figs. 1-2) a person wearing the glove pinches the pen with
the index and the thumb of the virtual hand; the session is analysed into the skill model
(contact schedule, object trajectory, wrench intensities). :class:`GloveSkillModelRecorder`
samples it from the env's MuJoCo state after reset and after every step, as
:class:`~ias_gym.skills.record.SkillModelRecorder` does for the pen-hand tasks, in the same
paper frame and units (see :mod:`ias_gym.sim.glove_contacts`):

- ``touching``: (index, thumb) touch the pen; ``sliding``: all False (a glove session has
  no sliding schedule);
- ``c`` (eq. 3): per finger the pen's contact wrench resolved as one soft-finger contact
  (the pads are MuJoCo condim-4 contacts): [normal, t1, t2] [N] at the finger's point and
  the torsion about the normal [N m] (eq. 16's columns and ``[0; n]``), 8 values;
- ``f_ext = W c`` (eq. 3), the fingers' net wrench on the pen, force and moment exactly,
  with W of :func:`ias_gym.sim.soft_finger.soft_wrench_matrix` (6 x 8);
- ``f_int = N^T c`` (eq. 10, two columns) and ``c_h = N N^T c`` (eq. 7): while both
  fingers touch W has rank 6, so G (eq. 8) exists and null(W) is two-dimensional; N is the
  named basis of :func:`~ias_gym.sim.soft_finger.pinch_null_basis`, the squeeze
  (positive when squeezing) and the opposed torsions; NaN unless both fingers touch.

Skills (:mod:`ias_gym.glove.skills`): an env made with ``skill=NAME`` performs that skill
after the pinch-lift; a recording stores it with ``Skill.name == NAME`` and
``env_kwargs["skill"] == NAME``, and the env's ``info["skill_phase"]`` at every sample (0
before the skill's own motion, 1 during it, 2 after): :func:`motion_window` reads the motion's
start and end from the record itself.

The env has no expert: a glove session is teleoperation (the ``teleop`` policy of
:func:`ias_gym.baselines.policies.load_policy`, zero action). Provenance: the person is the env's
(``env.unwrapped.person.person_id``) and the source names the glove
(:func:`glove_session_source`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ias_gym.baselines.policies import TELEOP
from ias_gym.skills.skill import Skill, SkillModelSamples

#: Internal forces of the soft-finger pinch: 8 intensities - rank 6 (eq. 6).
N_INTERNAL = 2

if TYPE_CHECKING:
    from ias_gym.envs.glove_grasp import GloveGraspEnv


def glove_session_source(source: str, glove_id: str) -> str:
    """Provenance of a glove session: ``glove:<glove_id>``, or ``<source>+glove:<glove_id>``.

    ``teleop`` (or ``glove``) becomes ``glove:<glove_id>``; a policy acting on top of the
    glove keeps its own source in front (``random+glove:sim-glove-0``); a source that names
    a glove already (contains ``glove:``) is kept as it is.
    """
    if "glove:" in source:
        return source
    if source in (TELEOP, "glove"):
        return f"glove:{glove_id}"
    return f"{source}+glove:{glove_id}"


class GloveSkillModelRecorder(SkillModelSamples):
    """Samples the skill model of a glove env, one :meth:`sample` per observation.

    Soft-finger pinch (module docstring): ``c`` has 8 columns, W is 6 x 8 of rank 6 while
    both fingers touch, so G (eq. 8) exists; ``f_int`` has two columns (the squeeze and the
    opposed torsions). The contacts are the env's own (``GloveGraspEnv.contact_pass``):
    the pass over MuJoCo's contacts that gave the step's force display also gives W and c.
    """

    def sample(self, env: GloveGraspEnv) -> None:
        """Append the contact schedule, pen state and wrench intensities of now.

        Args:
            env: the unwrapped glove env, just after ``reset`` or ``step``.

        Raises:
            RuntimeError: the env has not been reset.
        """
        # MuJoCo scene code: imported on first use, so that importing the skills package
        # (the database) does not load MuJoCo.
        from ias_gym.sim.soft_finger import pinch_null_basis

        if env.contact_pass is None:
            raise RuntimeError("sample the glove env after reset() or step()")
        p = env.physics
        contacts = p.finger_contacts(env.contact_pass)
        W, active = p.wrench_matrix(contacts)
        c = p.contact_intensities(contacts)
        N = pinch_null_basis(W, contacts)
        if N is not None:
            # G (eq. 8) exists: c = W+ W c + N N^T c (eqs. 4-7), f_int = N^T c (eq. 10).
            f_int = N.T @ c
            c_h = N @ f_int
        else:
            f_int = np.full(N_INTERNAL, np.nan)
            c_h = np.full(c.shape, np.nan)
        # sliding left out: a glove session has no sliding schedule
        self._append(time=env.data.time, pen=p, W=W, touching=active, c=c, c_h=c_h, f_int=f_int)


#: Demonstration info key of the skill's phase per sample (``IAS-GloveGrasp-v0``).
PHASE_INFO = "skill_phase"
#: Demonstration info keys of the person's intended pen height [m] and tilt [rad] per sample
#: (``IAS-GloveGrasp-v0``'s ``TARGET_INFO``).
TARGET_INFO: tuple[str, str] = ("target_height", "target_tilt")
#: The env whose sessions are a simulated person's (their parameters come from the id).
SIMULATED_TASK = "IAS-GloveGrasp-v0"


def motion_window(skill: Skill) -> tuple[float, float] | None:
    """``(start, end)`` [s] of a glove skill's own motion, from its record
    (:data:`PHASE_INFO`), or None for a record without phases (made before they were stored,
    or not a glove skill session). A skill that holds still (``lift_hold``) has
    ``start == end``.
    """
    phase = skill.demonstration.infos.get(PHASE_INFO)
    if phase is None:
        return None
    phase = np.asarray(phase)
    time = np.asarray(skill.model.time, dtype=np.float64)
    begun = np.flatnonzero(phase >= 1)
    if begun.size == 0:
        return None
    ended = np.flatnonzero(phase >= 2)
    start = float(time[begun[0]])
    return start, float(time[ended[0]]) if ended.size else float(time[-1])


def object_target(skill: Skill) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """``(height [m], tilt [rad])`` per sample: the object motion the person meant to do, from
    the record (:data:`TARGET_INFO`), or None for a record without it."""
    infos = skill.demonstration.infos
    if not all(key in infos for key in TARGET_INFO):
        return None
    height, tilt = (np.asarray(infos[key], dtype=np.float64) for key in TARGET_INFO)
    return height, tilt


def describe_session(skill: Skill) -> tuple[dict[str, NDArray[Any]], dict[str, float] | None, str]:
    """What a stored simulated person's session lacks of its own description, computed once.

    A session of :data:`SIMULATED_TASK` recorded with its phases (:data:`PHASE_INFO`: the
    person generator of today made it) but without its intended object motion
    (:data:`TARGET_INFO`) or its person's parameters gets them from the person generator by
    its person id and skill, as the env would have stored them (the motion starts at the
    recorded phase's start; the parameters are
    :func:`~ias_gym.glove.skills.person_parameters`). ``ias-gym skills migrate`` stores them
    (:meth:`~ias_gym.skills.db.SkillDB.describe`); no consumer recomputes them.

    Returns:
        ``(infos to add, person parameters to add or None, why a simulated person's session
        cannot be described: "" when it can, or when nothing is missing or it is no such
        session)``.
    """
    from ias_gym.glove.skills import SKILLS, SkillStyle, person_parameters, skill_object_target

    infos = skill.demonstration.infos
    # the env's skill (a glove skill's record is named after it, env_kwargs may be empty)
    name = skill.env_kwargs.get("skill", skill.name if skill.name in SKILLS else None)
    if skill.task != SIMULATED_TASK or skill.person_id is None:
        return {}, None, ""  # not a simulated person's session: nothing to describe
    if name is not None and name not in SKILLS:
        return {}, None, f"an unknown skill {name!r}"
    if PHASE_INFO not in infos:
        return (
            {},
            None,
            "recorded before sessions stored their phases, by a person generator that differs "
            "from today's: record it anew (`ias-gym skills record`)",
        )
    add: dict[str, NDArray[Any]] = {}
    if not all(key in infos for key in TARGET_INFO):
        style = SkillStyle.sample(skill.person_id)
        targets = np.array(
            [skill_object_target(name, float(t), style) for t in skill.model.time],
            dtype=np.float64,
        )
        add = {key: targets[:, i] for i, key in enumerate(TARGET_INFO) if key not in infos}
    person = None if skill.person_params is not None else person_parameters(skill.person_id)
    return add, person, ""

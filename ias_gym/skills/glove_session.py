"""Glove sessions as skills: the skill model of ``IAS-GloveGrasp-v0`` (paper secs. 2-3).

In the skill-acquisition loop (Figs. 1-2) a person wearing the glove pinches the pen with
the index and the thumb of the virtual hand; the session is analysed into the skill model
(contact schedule, object trajectory, wrench intensities). :class:`GloveSkillModelRecorder`
samples it from the env's MuJoCo state after reset and after every step, as
:class:`~ias_gym.skills.record.SkillModelRecorder` does for the pen-hand tasks, in the same
paper frame and units (see :mod:`ias_gym.sim.glove_contacts`):

- ``touching``: (index, thumb) touch the pen; ``sliding``: all False (a glove session has
  no sliding schedule);
- ``c`` (eq. 3): per finger the pen's contact force resolved as one point contact with
  friction [normal, t1, t2] at the finger's centre of pressure (eq. 16's columns), 6 values;
- ``f_ext = W c`` (eq. 3) with W built by :func:`ias_gym.grasp.contacts.wrench_matrix`;
- ``f_int = N^T c`` (eq. 10) and ``c_h = N N^T c`` (eq. 7), with N the unit null vector of
  the rank-5 W of the pinch (:func:`~ias_gym.sim.glove_contacts.squeeze_null_vector`),
  signed so that squeezing is positive; NaN unless both fingers touch. Two point contacts
  never make rank W = 6, so the grip transform G of eq. (8) does not exist here, but the
  internal force of the pinch - the squeeze along the line between the contacts - does.

The pads are soft contacts whose torsion has no column in the hard-finger c (eq. 16): W c
carries the fingers' net force exactly and their moment to about 2e-3 N m (see
:mod:`ias_gym.sim.glove_contacts`).

The env has no expert: a glove session is teleoperation (the ``teleop`` policy of
:func:`ias_gym.baselines.policies.load_policy`, zero action). Provenance: the person is the env's
(``env.unwrapped.person.person_id``) and the source names the glove
(:func:`glove_session_source`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ias_gym.baselines.policies import TELEOP
from ias_gym.skills.skill import SkillModelSamples

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
        from ias_gym.sim.glove_contacts import pinch_null_basis

        if env.contact_pass is None:
            raise RuntimeError("sample the glove env after reset() or step()")
        p = env.physics
        contacts = p.finger_contacts(env.contact_pass)
        W, active = p.wrench_matrix(contacts)
        c = p.contact_intensities(contacts)
        N = pinch_null_basis(W, contacts)
        if N is not None:
            # G (eq. 8) = [W+ N]^T-blocks: c = W+ W c + N N^T c (eqs. 4-7).
            f_int = N.T @ c
            c_h = N @ f_int
        else:
            f_int = np.full(N_INTERNAL, np.nan)
            c_h = np.full(c.shape, np.nan)
        # sliding left out: a glove session has no sliding schedule
        self._append(time=env.data.time, pen=p, W=W, touching=active, c=c, c_h=c_h, f_int=f_int)

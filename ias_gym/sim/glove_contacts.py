"""The glove scene's finger-pen contacts as the paper's point contacts with friction.

In ``IAS-GloveGrasp-v0`` the human hand touches the pen with several capsules per finger
(index: proximal, middle, distal phalanges and pad; thumb: metacarpal, proximal, distal and
pad), and MuJoCo may report several contacts for one finger at once (in the pinch the distal
phalanx and the pad capsule both press on the pen). The paper's skill model (sec. 3) has one
point contact with friction per finger, three wrench intensities each (eqs. 3, 16).
:class:`GlovePenPhysics` resolves each finger's contacts into one such contact:

- force: the sum of the forces of the finger's MuJoCo contacts on the pen (exact);
- point: their centre of pressure, the normal-force-weighted mean of the contact points
  (their plain mean if every normal force is zero); with one contact it is that contact's
  point;
- frame: normal = normal-force-weighted mean of the contact normals, oriented from the
  finger into the pen (the direction in which the finger pushes), t1 = the pen's axis made
  orthogonal to it, t2 = +-(t1 x n) as :class:`~ias_gym.sim.pen_hand.PenHandPhysics` does
  (sign fixed per finger: -1 for a finger that comes down on the pen from above, +1 for
  the others; for a vertical pinch t2 = paper +z for both, as in eq. 16).

What the hard-finger model leaves out is a moment: the pads are soft contacts (condim 4,
torsional friction; ``human_hand.xml``) whose torsion about the normal has no column in
eq. (16), and several contacts of one finger also make a moment about their centre of
pressure. So ``W c`` carries the fingers' net force exactly, and their moment up to
1.8e-3 N m (median 5e-4 N m; measured in the held pinch of ``IAS-GloveGrasp-v0``, seeds
0-3; the pen's weight times its radius is 1e-2 N m). :attr:`FingerContacts.moment` keeps
the exact moment (it matches MuJoCo's ``cfrc_ext``).

Frames and origin as :mod:`ias_gym.sim.pen_hand`: paper frame (x = MuJoCo x = the pen's
axis at rest, y = MuJoCo z = up, z = -MuJoCo y), positions relative to the pen's nominal
(model ``qpos0``) centre, moments about the pen's centre of mass. SI units.

State: contacts, forces, ``xipos`` and ``qacc`` come from the last forward pass (after
``mj_step``: the one at the start of its last substep, so they agree with each other);
:meth:`GlovePenPhysics.pen_pose` and :meth:`~GlovePenPhysics.pen_twist` read
``qpos``/``qvel`` (the state after the step), as the pen-hand physics does.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from ias_gym.grasp.contacts import wrench_matrix as _wrench_matrix
from ias_gym.grasp.grip_transform import RANK_RTOL
from ias_gym.sim.pen_hand import R_PAPER_TO_MJ, FreePenPhysics, mj_to_paper

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Rank of W for two point contacts with friction at distinct points: the moment about the
#: line through them cannot be produced (eq. 3), and the null space is the squeeze (eq. 6).
PINCH_RANK = 5


@dataclass(frozen=True)
class FingerContacts:
    """Each finger's pen contacts resolved as one point contact with friction (paper frame).

    Attributes:
        active: ``(k,)`` bool, some geom of finger i touches the pen.
        points: ``(k, 3)`` centre of pressure [m] (origin: nominal pen centre); the finger's
            tip site for a finger not touching.
        frames: ``(k, 3, 3)`` rows normal (the finger pushes along it), t1, t2; for a finger
            not touching, the normal points from the tip site to the pen's axis.
        force: ``(k, 3)`` summed force of finger i on the pen [N] (zero when not touching).
        moment: ``(k, 3)`` exact moment of finger i's contacts about the pen's centre of
            mass [N m], the pads' torsion included (``(points - com) x force`` approximates
            it, see the module docstring).
        count: ``(k,)`` number of MuJoCo contacts summed per finger.
    """

    active: BoolArray
    points: FloatArray
    frames: FloatArray
    force: FloatArray
    moment: FloatArray
    count: NDArray[np.int64]


class GlovePenPhysics(FreePenPhysics):
    """Named questions about the pen in a hand scene whose fingers are groups of geoms.

    The pen's pose, twist, centre of mass and mass are :class:`FreePenPhysics`'s, as for
    the pen-hand scene.

    Args:
        model: compiled scene (e.g. :func:`ias_gym.envs.glove_grasp.load_glove_scene`).
        data: its data.
        fingers: finger name -> names of its geoms whose pen contacts count, in the order
            of the skill model's columns (e.g. ``{"index": INDEX_GEOMS, "thumb": ...}``).
        tips: one site per finger (used for a finger that does not touch).
        above: per finger, it comes down on the pen from above (its t2 = -(t1 x n));
            default: none does.
        pen: name of the pen's body, free joint and geom.

    Raises:
        KeyError: a name is missing; the message lists the names that exist (for the pen a
            :class:`~ias_gym.sim.pen_hand.NameNotFoundError`, a ``KeyError``).
        ValueError: ``tips``, ``above`` and ``fingers`` differ in length, a geom is in
            two fingers, or the pen is not on a free joint with its centre of mass at its
            body origin.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        fingers: Mapping[str, Sequence[str]],
        tips: Sequence[str],
        above: Sequence[bool] | None = None,
        pen: str = "pen",
    ) -> None:
        above = [False] * len(fingers) if above is None else list(above)
        if not len(tips) == len(above) == len(fingers):
            raise ValueError(
                f"one tip site and one 'above' flag per finger of {list(fingers)}: got "
                f"{len(tips)} and {len(above)}"
            )
        super().__init__(model, data, pen)
        self.fingers: tuple[str, ...] = tuple(fingers)
        # geom id -> finger index; -1 for every other geom.
        self._finger_of_geom = np.full(model.ngeom, -1, dtype=np.int64)
        for i, names in enumerate(fingers.values()):
            for name in names:
                g = model.geom(name).id
                if self._finger_of_geom[g] >= 0:
                    raise ValueError(f"geom {name!r} is listed for two fingers")
                self._finger_of_geom[g] = i
        self.tip_site_ids = np.array([model.site(s).id for s in tips])
        # t2 = sign * (t1 x n). Fixed per finger, not from the normal's direction: a finger
        # pushing sideways would flip its frame with every wobble.
        self._t2_sign = np.where(above, -1.0, 1.0)
        self._force6 = np.zeros(6)

    @property
    def n_fingers(self) -> int:
        """Number of fingers k."""
        return len(self.fingers)

    # ------------------------------------------------------------------ pen
    # pen_pose, pen_twist, pen_com and pen_mass: from FreePenPhysics.

    def pen_acceleration(self) -> FloatArray:
        """Acceleration of the pen's centre of mass [m/s^2], paper frame, last forward pass.

        With it, Newton's law ``sum of contact forces + m g = m a`` holds to the solver's
        tolerance (the pen has no other loads).
        """
        return mj_to_paper(self.data.qacc[self.pen_dof_adr : self.pen_dof_adr + 3])

    # ------------------------------------------------------------------ contacts
    def other_contacts(self) -> list[str]:
        """Names of the geoms other than the fingers' that touch the pen (support, palm...)."""
        names = []
        for k in range(self.data.ncon):
            g1, g2 = int(self.data.contact[k].geom1), int(self.data.contact[k].geom2)
            if self.pen_geom_id in (g1, g2):
                other = g2 if g1 == self.pen_geom_id else g1
                if self._finger_of_geom[other] < 0:
                    names.append(mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_GEOM, other))
        return names

    def finger_contacts(self) -> FingerContacts:
        """Each finger's pen contacts as one point contact with friction (module docstring)."""
        m, d, k = self.model, self.data, self.n_fingers
        com_mj = d.xipos[self.pen_body_id]
        force = np.zeros((k, 3))
        moment = np.zeros((k, 3))
        weighted_point = np.zeros((k, 3))
        plain_point = np.zeros((k, 3))
        weighted_normal = np.zeros((k, 3))
        plain_normal = np.zeros((k, 3))
        weight = np.zeros(k)
        count = np.zeros(k, dtype=np.int64)
        for j in range(d.ncon):
            contact = d.contact[j]
            g1, g2 = int(contact.geom1), int(contact.geom2)
            if self.pen_geom_id not in (g1, g2):
                continue
            other = g2 if g1 == self.pen_geom_id else g1
            i = int(self._finger_of_geom[other])
            if i < 0:
                continue
            mujoco.mj_contactForce(m, d, j, self._force6)
            frame = contact.frame.reshape(3, 3)  # rows normal (geom1 -> geom2), t1, t2
            # The force of geom1 on geom2 (docs/DESIGN.md); the pen feels it if the pen is geom2.
            sign = 1.0 if g2 == self.pen_geom_id else -1.0
            f = sign * (frame.T @ self._force6[:3])
            normal_into_pen = sign * frame[0]
            w = max(float(self._force6[0]), 0.0)
            force[i] += f
            # The pads are soft contacts (condim 4): their torsion counts in the exact moment.
            moment[i] += np.cross(contact.pos - com_mj, f) + sign * (frame.T @ self._force6[3:])
            weighted_point[i] += w * contact.pos
            plain_point[i] += contact.pos
            weighted_normal[i] += w * normal_into_pen
            plain_normal[i] += normal_into_pen
            weight[i] += w
            count[i] += 1
        active = count > 0
        points = d.site_xpos[self.tip_site_ids].copy()
        normals = np.zeros((k, 3))
        axis = d.xmat[self.pen_body_id, [0, 3, 6]]
        for i in range(k):
            if not active[i]:
                # The geometric normal from the tip to the nearest point of the pen's axis.
                rel = points[i] - d.xpos[self.pen_body_id]
                u = np.clip(rel @ axis, -self._pen_half_length, self._pen_half_length)
                normals[i] = u * axis - rel
            elif weight[i] > 0:
                points[i] = weighted_point[i] / weight[i]
                normals[i] = weighted_normal[i]
            else:  # touching without force (a contact inside the margin): plain means
                points[i] = plain_point[i] / count[i]
                normals[i] = plain_normal[i]
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        t1 = axis - (normals @ axis)[:, None] * normals
        t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
        t2 = self._t2_sign[:, None] * np.cross(t1, normals)
        frames_mj = np.stack([normals, t1, t2], axis=1)
        return FingerContacts(
            active=active,
            points=mj_to_paper(points - self.origin_mj),
            frames=frames_mj @ R_PAPER_TO_MJ,
            force=mj_to_paper(force),
            moment=mj_to_paper(moment),
            count=count,
        )

    def wrench_matrix(self, contacts: FingerContacts) -> tuple[FloatArray, BoolArray]:
        """W of eqs. (3)/(16), ``(6, 3k)``, moments about the pen's centre of mass.

        Columns per finger [normal, t1, t2] of :class:`FingerContacts`; zero columns for a
        finger not touching. Returns ``(W, active)``.
        """
        w = _wrench_matrix(contacts.points, contacts.frames, reference=self.pen_com())
        if not contacts.active.all():
            w[:, np.repeat(~contacts.active, 3)] = 0.0
        return w, contacts.active

    @staticmethod
    def contact_intensities(contacts: FingerContacts) -> FloatArray:
        """Wrench intensities c of eq. (3), ``(3k,)`` [N]: each finger's force on the pen
        along its [normal, t1, t2] (normal >= 0 pushes); zeros for a finger not touching."""
        return np.einsum("kij,kj->ki", contacts.frames, contacts.force).reshape(-1)


def squeeze_null_vector(W: FloatArray, contacts: FingerContacts) -> FloatArray | None:
    """The unit null vector N of a two-finger pinch's W, signed so that squeezing is positive.

    With two point contacts with friction, W (6 x 6, eq. 3) has rank 5: no contact force
    makes a moment about the line through the two points. So the grip transform G of
    eq. (8), which needs rank W = 6, does not exist, but null(W) (eq. 6) is one-dimensional:
    the two fingers pushing towards each other along that line, ``c_h = N f_int`` (eq. 7).
    N is signed so that in ``N`` finger 1's force points towards finger 2: then
    ``f_int = N^T c`` (eq. 10) is positive when the fingers squeeze. With the unit N,
    ``f_int = sqrt(2) s`` for a squeeze of s [N] by each finger.

    Args:
        W: ``(6, 6)`` wrench matrix of two fingers (:meth:`GlovePenPhysics.wrench_matrix`).
        contacts: the contacts W was built from (their points fix the sign).

    Returns:
        ``(6,)`` unit vector with ``W N = 0``, or ``None`` unless both fingers touch and
        rank W = 5 (rank is judged as in :mod:`ias_gym.grasp.grip_transform`).
    """
    if W.shape != (6, 6) or not contacts.active.all():
        return None
    _, s, Vt = np.linalg.svd(W)
    rank = int(np.sum(s > RANK_RTOL * s[0])) if s[0] > 0 else 0
    if rank != PINCH_RANK:
        return None
    N = Vt[-1]
    toward_2 = contacts.points[1] - contacts.points[0]
    force_1 = contacts.frames[0].T @ N[:3]  # finger 1's force in N, paper frame
    return N if force_1 @ toward_2 >= 0 else -N

"""The glove scene's finger-pen contacts as the paper's contacts: soft fingers.

In ``IAS-GloveGrasp-v0`` the human hand touches the pen with several capsules per finger
(index: proximal, middle, distal phalanges and pad; thumb: metacarpal, proximal, distal and
pad), and MuJoCo may report several contacts for one finger at once (in the pinch the distal
phalanx and the pad capsule both press on the pen). The paper's skill model (sec. 3) has one
contact per finger. The pads are soft (MuJoCo ``condim=4``: friction plus torsional
friction about the normal; ``human_hand.xml``), so :class:`GlovePenPhysics` resolves each
finger's contacts into one *soft-finger* contact: a point contact with friction plus a
torsion about its normal, four wrench intensities (normal, t1, t2 [N], torsion [N m]):

- force: the sum of the forces of the finger's MuJoCo contacts on the pen (exact);
- moment: their exact moment about the pen's centre of mass, each contact's torsion
  included (MuJoCo's ``mj_contactForce`` gives it for condim 4);
- frame: normal = normal-force-weighted mean of the contact normals, oriented from the
  finger into the pen (the direction in which the finger pushes), t1 = the pen's axis made
  orthogonal to it, t2 = +-(t1 x n) as :class:`~ias_gym.sim.pen_hand.PenHandPhysics` does
  (sign fixed per finger: -1 for a finger that comes down on the pen from above, +1 for
  the others; for a vertical pinch t2 = paper +z for both, as in eq. 16);
- point: where the finger's force and moment are a force plus a torsion along the normal
  (:func:`~ias_gym.sim.soft_finger.soft_contact_points`): the centre of pressure
  (normal-force-weighted mean of the contact points) moved along the finger's force, by at
  most 1.3 mm (measured); with one contact it is that contact's point;
- torsion: the finger's moment about that point, along the normal.

The soft-finger model itself, its value type
:class:`~ias_gym.sim.soft_finger.FingerContacts` and its math (W, c, the friction cone, the
pinch's internal forces), is :mod:`ias_gym.sim.soft_finger`'s.

Frames and origin as :mod:`ias_gym.sim.pen`: paper frame (x = MuJoCo x = the pen's
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

from ias_gym.sim.contacts import axis_normals, contact_frames, cross
from ias_gym.sim.pen import R_PAPER_TO_MJ, FreePenPhysics, mj_to_paper
from ias_gym.sim.soft_finger import (
    FingerContacts,
    soft_contact_intensities,
    soft_contact_points,
    soft_wrench_matrix,
)

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: The zero torque of a contact's force applied at its point (``mj_applyFT``) [N m].
_NO_TORQUE = np.zeros(3)


@dataclass(frozen=True)
class PenContactPass:
    """One pass over MuJoCo's contacts of the pen (MuJoCo's world frame, SI units).

    :meth:`GlovePenPhysics.contact_pass` reads each finger-pen contact's force once; the
    force display uses the pass as it is (:attr:`qfrc`, :attr:`active`,
    :attr:`normal_force`, :attr:`other_geoms`), the skill model resolves it into
    :class:`FingerContacts` (:meth:`GlovePenPhysics.finger_contacts`). It keeps the pen's
    and the tips' positions of its forward pass, so it can be resolved later.

    Attributes:
        finger: ``(n,)`` finger index of each finger-pen contact, in MuJoCo's order.
        force6: ``(n, 6)`` MuJoCo's contact force and torque in the contact frame.
        frames: ``(n, 3, 3)`` MuJoCo's contact frames (rows normal geom1 -> geom2, t1, t2).
        pos: ``(n, 3)`` contact points [m].
        friction: ``(n, 2)`` each contact's sliding [-] and torsional [m] friction.
        sign: ``(n, 1)`` +1 where the pen is geom2 (it feels ``force6``), else -1.
        force: ``(n, 3)`` force of the finger on the pen [N].
        count: ``(k,)`` contacts per finger.
        normal_force: ``(k,)`` summed normal force of each finger's contacts [N] (as MuJoCo
            reports them).
        qfrc: ``(nv,)`` the pen's contact forces on the fingers as generalised forces,
            ``sum J^T (-force)`` with the finger bodies' Jacobians at the contact points
            [N m on hinges]: the force display's torques before the glove's joints are
            picked out.
        other_geoms: ids of the other geoms touching the pen (support, floor, palm...).
        com, centre, axis: the pen's centre of mass and body position [m] and its unit axis.
        tips: ``(k, 3)`` the fingers' tip sites [m].
    """

    finger: NDArray[np.int64]
    force6: FloatArray
    frames: FloatArray
    pos: FloatArray
    friction: FloatArray
    sign: FloatArray
    force: FloatArray
    count: NDArray[np.int64]
    normal_force: FloatArray
    qfrc: FloatArray
    other_geoms: frozenset[int]
    com: FloatArray
    centre: FloatArray
    axis: FloatArray
    tips: FloatArray

    @property
    def active(self) -> BoolArray:
        """``(k,)`` finger i touches the pen."""
        active: BoolArray = self.count > 0
        return active


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
            :class:`~ias_gym.sim.pen.NameNotFoundError`, a ``KeyError``).
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
        # The same maps as lists, for the per-step loop over the contacts.
        self._finger_of_list: list[int] = self._finger_of_geom.tolist()
        self._body_of_list: list[int] = model.geom_bodyid.tolist()
        self.tip_site_ids = np.array([model.site(s).id for s in tips])
        # A finger not touching gets the friction of its highest-priority geom (the pad's,
        # which sets the friction of the pad's contacts): sliding [-], torsional [m].
        friction = []
        for names in fingers.values():
            ids = [model.geom(name).id for name in names]
            top = max(ids, key=lambda g: int(model.geom_priority[g]))
            friction.append(model.geom_friction[top, :2])
        self._idle_friction = np.array(friction)
        # t2 = sign * (t1 x n). Fixed per finger, not from the normal's direction: a finger
        # pushing sideways would flip its frame with every wobble.
        self._t2_sign = np.where(above, -1.0, 1.0)

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

    def contact_pass(self) -> PenContactPass:
        """Read the pen's contacts once (:class:`PenContactPass`), from the last forward pass."""
        m, d, k = self.model, self.data, self.n_fingers
        pen = self.pen_geom_id
        contact = d.contact
        # One pass in Python over the few contacts (a handful per step): numpy's per-call
        # overhead on arrays this small costs more than the MuJoCo calls themselves.
        finger_of, body_of = self._finger_of_list, self._body_of_list
        sel: list[int] = []
        finger: list[int] = []
        signs: list[float] = []
        bodies: list[int] = []
        others: set[int] = set()
        for j, (g1, g2) in enumerate(contact.geom.tolist()):
            if g1 == pen:
                # The force of geom1 on geom2 (docs/DESIGN.md): the pen, geom1 here, feels
                # the opposite.
                other, side = g2, -1.0
            elif g2 == pen:
                other, side = g1, 1.0
            else:
                continue
            i = finger_of[other]
            if i < 0:
                others.add(other)
                continue
            sel.append(j)
            finger.append(i)
            signs.append(side)
            bodies.append(body_of[other])
        n = len(sel)
        force6 = np.empty((n, 6))
        frames = np.empty((n, 9))
        pos = np.empty((n, 3))
        friction = np.empty((n, 2))
        force = np.empty((n, 3))
        qfrc = np.zeros(m.nv)
        push = np.empty(3)
        count = [0] * k
        normal = [0.0] * k
        if n:
            all_frames = contact.frame
            all_pos = contact.pos
            all_friction = contact.friction
        for r, j in enumerate(sel):
            mujoco.mj_contactForce(m, d, j, force6[r])
            frames[r] = all_frames[j]
            pos[r] = all_pos[j]
            fr = all_friction[j]
            friction[r, 0], friction[r, 1] = fr[0], fr[2]
            # The force on the pen in the world: sign * frame^T (normal, t1, t2).
            fn, f1, f2 = force6[r, :3].tolist()
            e = frames[r].tolist()
            side = signs[r]
            fx = side * (fn * e[0] + f1 * e[3] + f2 * e[6])
            fy = side * (fn * e[1] + f1 * e[4] + f2 * e[7])
            fz = side * (fn * e[2] + f1 * e[5] + f2 * e[8])
            force[r, 0], force[r, 1], force[r, 2] = fx, fy, fz
            # The pen pushes the finger with -force, at the contact point on the finger's
            # body: qfrc += J^T (-force) (mj_applyFT, no torque: MuJoCo's point Jacobian).
            push[0], push[1], push[2] = -fx, -fy, -fz
            mujoco.mj_applyFT(m, d, push, _NO_TORQUE, pos[r], bodies[r], qfrc)
            i = finger[r]
            count[i] += 1
            normal[i] += fn
        b = self.pen_body_id
        return PenContactPass(
            finger=np.array(finger, dtype=np.int64),
            force6=force6,
            frames=frames.reshape(n, 3, 3),
            pos=pos,
            friction=friction,
            sign=np.array(signs).reshape(n, 1),
            force=force,
            count=np.array(count, dtype=np.int64),
            normal_force=np.array(normal),
            qfrc=qfrc,
            other_geoms=frozenset(others),
            com=d.xipos[b].copy(),
            centre=d.xpos[b].copy(),
            axis=d.xmat[b, 0:9:3].copy(),
            tips=d.site_xpos[self.tip_site_ids],
        )

    def finger_contacts(self, contact_pass: PenContactPass | None = None) -> FingerContacts:
        """Each finger's pen contacts as one soft-finger contact (module docstring).

        Args:
            contact_pass: the pass over the contacts to resolve (default: a new one). The
                env's pass of its last step (``GloveGraspEnv.contact_pass``) serves both the
                force display and the skill model.
        """
        cp = self.contact_pass() if contact_pass is None else contact_pass
        k = self.n_fingers
        frames, pos, sign, f = cp.frames, cp.pos, cp.sign, cp.force
        # The pads are soft contacts (condim 4): their torsion counts in the exact moment.
        torque = sign * np.einsum("nji,nj->ni", frames, cp.force6[:, 3:])
        moments = cross(pos - cp.com, f) + torque
        normal_into_pen = sign * frames[:, 0]
        w = np.maximum(cp.force6[:, 0], 0.0)
        # Sums per finger: finger i's rows of a (k, n) one-hot matrix.
        onehot = (cp.finger[None, :] == np.arange(k)[:, None]).astype(float)
        weight = onehot @ w
        active = cp.active
        points = cp.tips.copy()
        normals = np.zeros((k, 3))
        for i in range(k):
            if not active[i]:
                # The geometric normal from the tip to the nearest point of the pen's axis.
                normals[i] = axis_normals(
                    points[i : i + 1], cp.centre, cp.axis, self._pen_half_length
                )[0]
            elif weight[i] > 0:
                points[i] = (onehot[i] * w) @ pos / weight[i]
                normals[i] = (onehot[i] * w) @ normal_into_pen
            else:  # touching without force (a contact inside the margin): plain means
                points[i] = onehot[i] @ pos / cp.count[i]
                normals[i] = onehot[i] @ normal_into_pen
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        frames_mj = contact_frames(normals, cp.axis, self._t2_sign)
        force, moment = onehot @ f, onehot @ moments
        points = soft_contact_points(points, normals, force, moment, cp.com, active)
        # The soft finger's torsion: the finger's moment about its own point, along its
        # normal (the part of that moment the point's force columns cannot make).
        about_point = moment - cross(points - cp.com, force)
        torsion = np.where(active, np.einsum("ij,ij->i", about_point, normals), 0.0)
        friction = self._idle_friction.copy()
        for j in np.flatnonzero(active):
            mine = np.flatnonzero(cp.finger == j)
            friction[j] = cp.friction[mine[np.argmax(cp.force6[mine, 0])]]
        return FingerContacts(
            active=active,
            points=mj_to_paper(points - self.origin_mj),
            frames=frames_mj @ R_PAPER_TO_MJ,
            force=mj_to_paper(force),
            moment=mj_to_paper(moment),
            count=cp.count,
            torsion=torsion,
            friction=friction,
        )

    def wrench_matrix(self, contacts: FingerContacts) -> tuple[FloatArray, BoolArray]:
        """W of eqs. (3)/(16) for soft fingers, ``(6, 4k)``, moments about the pen's centre
        of mass.

        Columns per finger [normal, t1, t2] of :class:`FingerContacts` (eq. 16) and the
        torsion column ``[0; n]``; zero columns for a finger not touching. Returns
        ``(W, active)``.
        """
        return soft_wrench_matrix(contacts, self.pen_com()), contacts.active

    @staticmethod
    def contact_intensities(contacts: FingerContacts) -> FloatArray:
        """Wrench intensities c of eq. (3) for soft fingers, ``(4k,)``: each finger's force
        on the pen along its [normal, t1, t2] [N] (normal >= 0 pushes) and its torsion
        about the normal [N m]; zeros for a finger not touching."""
        return soft_contact_intensities(contacts)

"""The physics side of the pen-hand scene: named questions about a compiled MuJoCo model.

:class:`PenHandPhysics` wraps ``(model, data)`` of ``assets/scene_pen.xml`` (the four-finger
IAS hand holding the pen of the paper's sec. 3.2) in the spirit of dm_control's ``Physics``:
names are looked up once in ``__init__``, every method then indexes by id and answers one
question in the paper's terms - the wrench matrix W (eqs. 3, 16), the contact intensities c,
the hand Jacobian J (eq. 30), the hand's M and H (eq. 35), the pen's pose (eq. 25), twist
(eq. 15), mass and inertia (eq. 33). The pen's part (:class:`FreePenPhysics`: pose, twist,
mass of a pen on a free joint, and the paper frame: :mod:`ias_gym.sim.pen`) is shared
with the glove scene's physics.

Frames. The paper frame has x = pen axis, y = vertical (up), z = lateral. MuJoCo's world has
z up, so ``paper x = MuJoCo x``, ``paper y = MuJoCo z``, ``paper z = -MuJoCo y``
(a right-handed rotation by +90 degrees about x): ``v_mj = R_PAPER_TO_MJ @ v_paper``.
Every vector this class returns is in the paper frame; positions have their origin at the
nominal pen centre (the pen body's position in the XML, MuJoCo (0, 0, 0.2) m). The pen's own
frame at rest coincides with the paper frame.

State. Contacts, Jacobians, M and H come from the last ``mj_forward``/``mj_step`` (MuJoCo's
``d.contact``, ``d.xpos``, ``d.qM``, ...); :meth:`PenHandPhysics.pen_pose`,
:meth:`~PenHandPhysics.pen_twist` and the ``hand_q*`` methods read ``qpos``/``qvel`` directly.
Units are SI (m, rad, N, N m, kg).
"""

from __future__ import annotations

import importlib.resources
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ias_gym.sim.contacts import (
    PointContacts,
    axis_normals,
    contact_frames,
    contact_intensities,
    cross,
    masked_wrench_matrix,
)
from ias_gym.sim.external_hands import BUILDERS, coupled_joints
from ias_gym.sim.hands import DEFAULT_HAND, get_hand
from ias_gym.sim.pen import (
    R_PAPER_TO_MJ,
    FreePenPhysics,
    NameNotFoundError,
    lookup,
    matrix_to_rpy,
    mj_to_paper,
    paper_to_mj,
    rpy_to_matrix,
    wrench_mj_to_paper,
    wrench_paper_to_mj,
)

#: Public names, with those of :mod:`ias_gym.sim.pen` that were first defined here.
__all__ = [
    "FINGERS",
    "FINGER_JOINTS",
    "GRASP_KEYFRAME",
    "R_PAPER_TO_MJ",
    "SCENE_FILE",
    "FingertipContacts",
    "FreePenPhysics",
    "NameNotFoundError",
    "PenHandPhysics",
    "load_pen_hand_model",
    "matrix_to_rpy",
    "mj_to_paper",
    "paper_to_mj",
    "rpy_to_matrix",
    "wrench_mj_to_paper",
    "wrench_paper_to_mj",
]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Finger name prefixes in the MJCF, in the paper's order (1, 2, 3, 4).
FINGERS: tuple[str, ...] = ("f1", "f2", "f3", "f4")
#: Joint suffixes per finger, proximal to distal.
FINGER_JOINTS: tuple[str, ...] = ("abd", "mcp", "pip")
#: Scene file in ``ias_gym.assets``.
SCENE_FILE = "scene_pen.xml"
#: Values of each ``fN_pen_contact`` sensor: found, force (3), dist, pos (3), normal (3),
#: tangent (3).
_CONTACT_SENSOR_DIM = 14
#: Keyframe with the paper's four-finger grasp (phi = [3, 2, 2, 3] cm).
GRASP_KEYFRAME = "grasp"


def load_pen_hand_model(scene: str = SCENE_FILE) -> mujoco.MjModel:
    """Compile a scene of ``ias_gym.assets`` (default: the pen-hand scene).

    The scene includes ``ias_hand.xml`` and ``pen.xml`` by relative path, so it is compiled
    from its real path on disk (``importlib.resources.as_file``). A name of
    :data:`ias_gym.sim.external_hands.BUILDERS` (``"shadow"``) is built by its builder.
    """
    if scene in BUILDERS:  # a hand another project built, from its installed package
        return BUILDERS[scene]()
    resource = importlib.resources.files("ias_gym.assets") / scene
    with importlib.resources.as_file(resource) as path:
        return mujoco.MjModel.from_xml_path(str(path))


@dataclass(frozen=True)
class FingertipContacts(PointContacts):
    """The fingertip-pen contacts of one instant, one row per finger (paper frame).

    Attributes:
        active: ``(k,)`` bool, finger touches the pen.
        points: ``(k, 3)`` contact points [m] (MuJoCo's: midway through the penetration),
            origin at the nominal pen centre; the tip-site centre for a finger not touching.
        frames: ``(k, 3, 3)`` rows normal, t1, t2. The normal is the direction in which the
            finger pushes on the pen; t1 is the pen's own axis (made orthogonal to the normal);
            t2 = +-(t1 x n), the sign fixed per finger so that t2 = +z for the untilted pen,
            as eq. (16) uses (this makes the frames of the top fingers left-handed). For a
            finger not touching, the normal points from the tip centre to the pen's axis.
        depth: ``(k,)`` penetration [m] (positive = overlapping); 0 when not touching.
        force: ``(k, 3)`` force of each fingertip on the pen [N] (zero when not touching).
    """

    depth: FloatArray


class PenHandPhysics(FreePenPhysics):
    """Named, vectorised questions about the pen-hand scene (paper frame, SI units).

    Args:
        model: compiled scene (see :func:`load_pen_hand_model`).
        data: its data.
        fingers: finger name prefixes; finger ``f`` needs joints ``f_abd``, ``f_mcp``,
            ``f_pip`` (each driven by one actuator), site ``f_tip``, geom ``f_tip_collision``
            and touch sensor ``f_touch``.
        pen: name of the pen's body, free joint and geom.
        finger_joints: joint suffixes per finger, proximal to distal (the same for every
            finger).
        sides: per finger, the side of the pen it touches (+1 top, -1 bottom); ``None``: the
            side its base is on (a hand whose bases all sit below the pen needs them).

    Attributes:
        n_fingers, n_hand_dofs: k fingers and their hinge dofs (3k for abd, mcp, pip).
        finger_sides: ``(k,)`` the side of the pen each finger's base is on: +1 above the
            pen's centre (pushes down), -1 below.
        hand_qpos_ids, hand_dof_ids, hand_actuator_ids: ``(3k,)`` indices into ``qpos``,
            ``qvel``/``qfrc_*`` and ``ctrl``, in the order f1 abd, mcp, pip, f2 ...
        coupled: ``(follower dof, hand joint index, ratio)`` per joint that no motor drives
            but a joint equality ties to a hand joint (``follower = ratio * leader``, the
            Shadow hand's distal joints). The hand's coordinates are the driven joints; M,
            H and J are those of the coupled system (``S^T M S``, ``S^T H``, ``J S`` with
            ``S`` the map from driven to all joint velocities), so the equality's own force
            drops out of eq. (35).
        tip_site_ids, tip_geom_ids: ``(k,)`` fingertip sites and collision spheres.
        pen_body_id, pen_geom_id, pen_qpos_adr, pen_dof_adr, origin_mj: the pen's ids, its
            free joint's addresses and its nominal centre [m] (:class:`FreePenPhysics`).

    Raises:
        NameNotFoundError: a name is missing; the message lists the names that exist.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        fingers: Sequence[str] = FINGERS,
        pen: str = "pen",
        finger_joints: Sequence[str] = FINGER_JOINTS,
        sides: Sequence[float] | None = None,
    ) -> None:
        super().__init__(model, data, pen)
        self.fingers: tuple[str, ...] = tuple(fingers)
        k = len(self.fingers)
        obj = mujoco.mjtObj

        joints = [
            lookup(model, obj.mjOBJ_JOINT, f"{f}_{j}") for f in fingers for j in finger_joints
        ]
        self.hand_qpos_ids = np.array([model.jnt_qposadr[j] for j in joints])
        self.hand_dof_ids = np.array([model.jnt_dofadr[j] for j in joints])
        self._dof_ix = np.ix_(self.hand_dof_ids, self.hand_dof_ids)
        # The actuator driving each hand joint (found by transmission, not by name).
        act_of_joint = {
            int(model.actuator_trnid[a, 0]): a
            for a in range(model.nu)
            if int(model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT)
        }
        missing = [
            mujoco.mj_id2name(model, obj.mjOBJ_JOINT, j) for j in joints if j not in act_of_joint
        ]
        if missing:
            raise ValueError(f"hand joints without a joint actuator: {missing}")
        self.hand_actuator_ids = np.array([act_of_joint[j] for j in joints])
        self._gear = model.actuator_gear[self.hand_actuator_ids, 0].copy()

        self.tip_site_ids = np.array([lookup(model, obj.mjOBJ_SITE, f"{f}_tip") for f in fingers])
        self.tip_geom_ids = np.array(
            [lookup(model, obj.mjOBJ_GEOM, f"{f}_tip_collision") for f in fingers]
        )
        self._tip_bodies = model.geom_bodyid[self.tip_geom_ids].copy()
        touch = [lookup(model, obj.mjOBJ_SENSOR, f"{f}_touch") for f in fingers]
        self._touch_adr = model.sensor_adr[touch].copy()
        contact = [lookup(model, obj.mjOBJ_SENSOR, f"{f}_pen_contact") for f in fingers]
        if np.any(model.sensor_dim[contact] != _CONTACT_SENSOR_DIM):
            raise ValueError(
                "the fN_pen_contact sensors must have data='found force dist pos normal "
                f"tangent' ({_CONTACT_SENSOR_DIM} values each)"
            )
        self._contact_sensor_idx = (
            model.sensor_adr[contact][:, None] + np.arange(_CONTACT_SENSOR_DIM)
        ).ravel()

        # t2 = sign * (t1 x n): -1 for fingers above the pen axis (push down), +1 below, so
        # that t2 = +z (paper) for all fingers at the untilted pen (eq. 16).
        if sides is None:
            scratch = mujoco.MjData(model)
            mujoco.mj_kinematics(model, scratch)
            base_z = scratch.xpos[model.jnt_bodyid[joints[:: len(joints) // k]], 2]
            self._t2_sign = np.where(base_z > self.origin_mj[2], -1.0, 1.0)
        else:
            if len(sides) != k:
                raise ValueError(f"sides needs one entry per finger ({k}), got {len(sides)}")
            self._t2_sign = -np.asarray(sides, dtype=float)
        self.finger_sides = -self._t2_sign
        self.coupled = coupled_joints(model, joints)
        self._all_dofs = self.hand_dof_ids
        self._coupling: FloatArray | None = None  # S, when some joint follows another
        if self.coupled:
            n = len(joints)
            self._all_dofs = np.r_[self.hand_dof_ids, [dof for dof, _, _ in self.coupled]]
            self._coupling = np.zeros((len(self._all_dofs), n))
            self._coupling[:n] = np.eye(n)
            for row, (_, leader, ratio) in enumerate(self.coupled, start=n):
                self._coupling[row, leader] = ratio
            self._dof_ix = np.ix_(self._all_dofs, self._all_dofs)
        # Geoms of the hand (same kinematic tree as the fingertips), for link-contact checks.
        hand_root = model.body_rootid[self._tip_bodies[0]]
        self._hand_geom = model.body_rootid[model.geom_bodyid] == hand_root
        self._hand_geom[self.tip_geom_ids] = False

        self.n_fingers = k
        self.n_hand_dofs = len(joints)
        self._full_m = np.zeros((model.nv, model.nv))

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_assets(
        cls, keyframe: str | None = GRASP_KEYFRAME, hand: str = DEFAULT_HAND
    ) -> PenHandPhysics:
        """Load a hand's pen scene, make its data, reset to ``keyframe`` (if given).

        Args:
            keyframe: keyframe to reset to (``None``: ``qpos0``).
            hand: a name of :data:`ias_gym.sim.hands.HANDS`.

        Raises:
            InputError: an unknown hand (the message lists the known ones).
        """
        spec = get_hand(hand)
        model = load_pen_hand_model(spec.scene)
        physics = cls(
            model, mujoco.MjData(model), spec.fingers, finger_joints=spec.joints, sides=spec.sides
        )
        physics.reset(keyframe)
        return physics

    def reset(self, keyframe: str | None = GRASP_KEYFRAME) -> None:
        """Reset the data to a keyframe (or to ``qpos0`` if None) and run ``mj_forward``."""
        if keyframe is None:
            mujoco.mj_resetData(self.model, self.data)
        else:
            key = lookup(self.model, mujoco.mjtObj.mjOBJ_KEY, keyframe)
            mujoco.mj_resetDataKeyframe(self.model, self.data, key)
        mujoco.mj_forward(self.model, self.data)

    # ------------------------------------------------------------------ hand
    def hand_qpos(self) -> FloatArray:
        """Hand joint angles theta [rad], ``(n_hand_dofs,)``, fingers in order, abd/mcp/pip."""
        return self.data.qpos[self.hand_qpos_ids]

    def hand_qvel(self) -> FloatArray:
        """Hand joint velocities [rad/s], ``(n_hand_dofs,)``."""
        return self.data.qvel[self.hand_dof_ids]

    def set_hand_torques(self, tau: ArrayLike) -> None:
        """Command joint torques tau [N m] (eq. 35) through the motors (``ctrl = tau / gear``).

        MuJoCo clamps ``ctrl`` to each motor's ctrlrange.
        """
        self.data.ctrl[self.hand_actuator_ids] = np.asarray(tau, dtype=float) / self._gear

    def hand_torques(self) -> FloatArray:
        """Joint torques [N m] the motors apply now (after MuJoCo's clamping)."""
        return self.data.qfrc_actuator[self.hand_dof_ids]

    def hand_mass_matrix(self) -> FloatArray:
        """The hand's joint-space inertia M(theta) of eq. (35) [kg m^2], ``(n, n)``.

        Block diagonal (one 3x3 block per finger); includes the joints' armature.
        """
        mujoco.mj_fullM(self.model, self.data, self._full_m)
        if self._coupling is None:
            return self._full_m[self._dof_ix]
        out: FloatArray = self._coupling.T @ self._full_m[self._dof_ix] @ self._coupling
        return out

    def hand_bias_forces(self) -> FloatArray:
        """H(theta, theta_dot) of eq. (35) [N m]: every joint force but motors and contacts.

        ``qfrc_bias - qfrc_passive`` on the hand dofs: Coriolis/centrifugal and gravity
        (``qfrc_bias``) minus the gravity compensation of the ``gravcomp`` bodies
        (``qfrc_gravcomp``, which ``qfrc_bias`` does not know about - forgetting it
        compensates gravity twice), plus the joints' damping. With it,
        ``M theta_ddot + H = tau - J^T c`` holds exactly (away from joint limits).
        """
        d = self.data
        return self.hand_forces(d.qfrc_bias - d.qfrc_passive)

    def hand_forces(self, qfrc: FloatArray) -> FloatArray:
        """A joint-force vector of the whole model ``(nv,)`` on the hand's coordinates
        [N m]: its hand entries, with a coupled joint's added to its leader's times the
        ratio (``S^T qfrc``)."""
        if self._coupling is None:
            out: FloatArray = qfrc[self.hand_dof_ids]
            return out
        coupled: FloatArray = self._coupling.T @ qfrc[self._all_dofs]
        return coupled

    def hand_damping(self, coulomb: bool = False) -> FloatArray:
        """The hand coordinates' viscous damping [N m s/rad], ``(n_hand_dofs,)`` (a coupled
        joint's adds ``ratio**2`` times its own to its leader's: ``diag(S^T D S)``); with
        ``coulomb``, their Coulomb friction (MuJoCo's ``frictionloss``) [N m], a coupled
        joint's added ``|ratio|`` times."""
        damping = (self.model.dof_frictionloss if coulomb else self.model.dof_damping)[
            self._all_dofs
        ]
        if self._coupling is None:
            return damping.copy()
        out: FloatArray = (np.abs(self._coupling) ** (1 if coulomb else 2)).T @ damping
        return out

    def tip_positions(self) -> FloatArray:
        """Fingertip (sphere centre) positions [m], ``(k, 3)``, paper frame."""
        return mj_to_paper(self.data.site_xpos[self.tip_site_ids] - self.origin_mj)

    def touch(self) -> FloatArray:
        """Touch-sensor readings [N] per fingertip (normal force summed over its contacts)."""
        return self.data.sensordata[self._touch_adr]

    # ------------------------------------------------------------------ pen
    # pen_rotation, pen_pose, pen_twist, pen_com and pen_mass: from FreePenPhysics.

    def pen_axis(self) -> FloatArray:
        """Unit vector along the pen's axis (its own x), paper frame; independent of roll."""
        return mj_to_paper(self._pen_rot()[:, 0])

    def pen_inertia(self, nominal: bool = False) -> FloatArray:
        """Pen inertia tensor about its centre of mass [kg m^2], paper frame (eq. 33's J).

        MuJoCo stores principal moments in the inertial frame (``body_inertia``); rotated here
        with ``ximat`` of the last forward pass.

        Args:
            nominal: the principal moments of the model as built (``pen_mass_nominal``'s
                counterpart), not the simulated ones.
        """
        rot = self.data.ximat[self.pen_body_id].reshape(3, 3)
        moments = (
            self._pen_inertia_nominal if nominal else self.model.body_inertia[self.pen_body_id]
        )
        inertia_mj = (rot * moments) @ rot.T
        return R_PAPER_TO_MJ.T @ inertia_mj @ R_PAPER_TO_MJ

    # ------------------------------------------------------------------ contacts
    def fingertip_contacts(self) -> FingertipContacts:
        """The tip-pen contact of every finger, with the paper's contact frame (eq. 16).

        Read from the scene's contact sensors ``fN_pen_contact`` (MuJoCo fills them in the
        forward pass: the deepest tip-pen contact's point, normal, first tangent and force,
        oriented from the tip to the pen whichever geom MuJoCo lists first), so no Python
        loop over ``data.contact`` is needed.
        """
        d, k = self.data, self.n_fingers
        block = d.sensordata[self._contact_sensor_idx].reshape(k, _CONTACT_SENSOR_DIM)
        active = block[:, 0] > 0
        everyone = bool(active.all())
        # The pen's axis from the same forward pass as the contacts (not from qpos).
        axis_mj = d.xmat[self.pen_body_id, 0::3]  # the first column of the rotation
        normal_mj = block[:, 8:11]  # unit vectors from MuJoCo
        points_mj = block[:, 5:8]
        if not everyone:
            # For fingers that do not touch: the tip centre, and the geometric normal from it
            # to the nearest point of the pen's axis segment.
            idle = ~active
            tips_mj = d.site_xpos[self.tip_site_ids]
            normal_mj, points_mj = normal_mj.copy(), points_mj.copy()
            normal_mj[idle] = axis_normals(
                tips_mj[idle], d.xpos[self.pen_body_id], axis_mj, self._pen_half_length
            )
            points_mj[idle] = tips_mj[idle]
        # Force of the tip on the pen: MuJoCo's contact frame is (normal, tangent, n x t).
        tangent = block[:, 11:14]
        binormal = cross(normal_mj, tangent)
        f = block[:, 1:4]
        force_mj = f[:, :1] * normal_mj + f[:, 1:2] * tangent + f[:, 2:3] * binormal
        if not everyone:
            force_mj[~active] = 0.0

        # Frame rows in MuJoCo coordinates, converted to the paper frame in one product
        # (t2 = sign * (t1 x n): the paper frame is a proper rotation of MuJoCo's, so the
        # cross product commutes with the conversion).
        frames = contact_frames(normal_mj, axis_mj, self._t2_sign)
        return FingertipContacts(
            active=active,
            points=(points_mj - self.origin_mj) @ R_PAPER_TO_MJ,
            frames=frames @ R_PAPER_TO_MJ,
            depth=-block[:, 4] if everyone else np.where(active, -block[:, 4], 0.0),
            force=force_mj @ R_PAPER_TO_MJ,
        )

    def wrench_matrix(
        self, contacts: FingertipContacts | None = None
    ) -> tuple[FloatArray, BoolArray]:
        """The wrench matrix W of eqs. (3)/(16) from the simulated contacts.

        Moments are about the pen's centre of mass, everything in the (world-aligned) paper
        frame; columns per finger [normal, t1, t2] as in :class:`FingertipContacts`.

        Args:
            contacts: from :meth:`fingertip_contacts` (computed if not given).

        Returns:
            ``(W, active)``: W ``(6, 3k)`` with zero columns for fingers not touching, and the
            ``(k,)`` bool mask of touching fingers.
        """
        c = self.fingertip_contacts() if contacts is None else contacts
        return masked_wrench_matrix(c, self.pen_com()), c.active

    def contact_intensities(self, contacts: FingertipContacts | None = None) -> FloatArray:
        """The measured wrench intensities c of eq. (3), ``(3k,)`` [N].

        Per finger the force the finger applies to the pen along [normal, t1, t2] of its
        contact frame (normal >= 0 pushes); zeros for a finger not touching. With the pen's
        other loads, ``W @ c`` is the fingers' net wrench.
        """
        return contact_intensities(self.fingertip_contacts() if contacts is None else contacts)

    def fingertip_jacobians(self, contacts: FingertipContacts | None = None) -> FloatArray:
        """The hand Jacobian J of eq. (30), ``(3k, n_hand_dofs)``.

        Row block i maps hand joint velocities [rad/s] to the velocity [m/s] of finger i's
        contact point (fixed to the fingertip; the tip centre when not touching) along its
        [normal, t1, t2]. So ``J.T @ c`` are the joint torques [N m] that the contact
        intensities c correspond to: the contacts load the hand with ``-J.T @ c`` (eq. 35).
        """
        cts = self.fingertip_contacts() if contacts is None else contacts
        frames_mj = paper_to_mj(cts.frames)  # rows n, t1, t2 in MuJoCo coordinates
        points_mj = paper_to_mj(cts.points) + self.origin_mj
        # Every finger's translational Jacobian, then one stacked product with the frames
        # (numpy multiplies each matrix of a stack as it would alone: the same bits).
        jacp = np.empty((self.n_fingers, 3, self.model.nv))
        for i in range(self.n_fingers):
            mujoco.mj_jac(self.model, self.data, jacp[i], None, points_mj[i], self._tip_bodies[i])
        if self._coupling is None:
            jac = frames_mj @ jacp[:, :, self.hand_dof_ids]
        else:
            jac = frames_mj @ (jacp[:, :, self._all_dofs] @ self._coupling)
        return jac.reshape(3 * self.n_fingers, self.n_hand_dofs)

    def n_link_contacts(self) -> int:
        """Number of hand-pen contacts not at a fingertip (a finger link touching the pen)."""
        geom = self.data.contact.geom
        other = np.where(geom[:, 0] == self.pen_geom_id, geom[:, 1], geom[:, 0])
        pen_pair = (geom[:, 0] == self.pen_geom_id) | (geom[:, 1] == self.pen_geom_id)
        return int(np.count_nonzero(pen_pair & self._hand_geom[other]))

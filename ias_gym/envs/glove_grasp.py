"""IAS-GloveGrasp-v0: the sensor glove drives a human hand that pinches and lifts the pen.

Paper 2.1-2.4 (the skill-acquisition loop of Figs. 1-2): every control step the glove is read
(readings Ψ [rad]), the person's calibration maps them to joint angles Θ = f(Ψ) (eq. (1)),
and these become the position targets of the hand model's actuators, plus the agent's
offsets. The contact forces of the pen on the index and thumb pads are mapped to torques on
the glove's actuated joints, ``tau = J^T f`` (force display), observed and written back to
the glove (``device.write_feedback``).

The scene (``scene_glove.xml`` = ``human_hand.xml`` + ``pen.xml`` + a support) is built per
person by :func:`load_glove_scene` (hand rescaled with :class:`mujoco.MjSpec`, the pen placed
between the person's thumb and index pads).
"""

from __future__ import annotations

import dataclasses
import importlib.resources
import math
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from ias_gym.errors import InputError
from ias_gym.glove.calibration import Calibration
from ias_gym.glove.device import ACTUATED_JOINTS, GloveDevice, ReachPinchLift, SimulatedGlove
from ias_gym.glove.hand import (
    JOINT_HIGH,
    JOINT_LOW,
    JOINT_NAMES,
    PersonParams,
    hand_points,
    thumb_directions,
)
from ias_gym.glove.ids import check_id
from ias_gym.glove.profile import ProfileError, load_profile, save_profile

FloatArray = NDArray[np.float64]

SCENE_FILE = "scene_glove.xml"
#: Wrist centre to index MCP along the metacarpal at hand scale 1 [m] (human_hand.xml).
NOMINAL_WRIST_TO_MCP = 0.095
#: Tip-to-tip distance of the operator's pen pinch minus the pen's diameter, at scale 1 [m].
#: The model's pads need +13 mm (index 6 mm + thumb 7 mm radius); the targets lie 17 mm
#: (+ ReachPinchLift's 2 mm) further in, so the position servos squeeze the pen with about
#: 2 N (measured; the pen weighs 1 N, mu = 0.25).
PEN_PAD_GAP = -0.004
#: Pen pinches (thumb CMC, thumb flexion, index DIP) [rad], the first in reach is used:
#: poses where the shipped ANN calibration is accurate (<= 2 deg on p1's and p3's index and
#: thumb; the glove's calibration poses are bare-pad pinches and free poses).
PEN_PINCH_POSES: tuple[tuple[float, float, float], ...] = (
    (1.1, 0.4, 0.4),
    (1.0, 0.4, 0.4),
    (1.0, 0.6, 0.6),
    (1.1, 0.4, 0.2),
    (1.0, 0.2, 0.4),
)
PEN_RADIUS = 0.01  # pen.xml [m]
#: The two posts the pen rests on: half width [m], distance of each from the pen's middle
#: along the pen [m] (the thumb passes between them).
POST_HALF_WIDTH = 0.006
POST_OFFSET = 0.04
#: The cradle rods on the posts: radius [m], half their spacing across the pen [m].
ROD_RADIUS = 0.002
ROD_SPACING = 0.006
THUMB_PAD_RADIUS = 0.007  # human_hand.xml, scale 1 [m]
#: The pinch pose's wrist flexion [rad] (ReachPinchLift's open/pinch wrist angle).
PINCH_WRIST_FLEXION = -0.1
#: Forearm pitch [rad]: the fingers point down by this much at zero wrist angles, so that the
#: thumb, under the pen, still slopes down distally when the wrist extends to lift.
FOREARM_PITCH = 0.3
#: Names of the hand's geoms whose pen contacts make up the force display, per finger.
INDEX_GEOMS = ("index_proximal", "index_middle", "index_distal", "index_pad")
THUMB_GEOMS = ("thumb_metacarpal", "thumb_proximal", "thumb_distal", "thumb_pad")
#: Geoms the pen rests on before the lift.
SUPPORT_GEOMS = (
    "floor",
    "support_left",
    "support_right",
    *(f"cradle_{side}_{rod}" for side in ("left", "right") for rod in ("a", "b")),
)
#: Where the pad capsules sit along the distal phalanges (fraction of the length).
PAD_AT = 0.75
#: thumb MCP-share and IP hinges = this x thumb_flexion (equalities of human_hand.xml).
THUMB_IP_RATIO_SHARE = 0.45


def forearm_frame(pitch: float) -> FloatArray:
    """Rotation world <- hand frame at zero wrist angles: palm down, fingers along world +y
    tilted down by ``pitch`` [rad]; the hand's z (flexion axis) is along world -x."""
    x = np.array([0.0, math.cos(pitch), -math.sin(pitch)])
    y = np.array([0.0, -math.sin(pitch), -math.cos(pitch)])
    return np.column_stack([x, y, np.cross(x, y)])


def pen_operator(person: PersonParams) -> ReachPinchLift:
    """The scripted operator pinching the pen: :class:`ReachPinchLift` with the pads apart.

    ReachPinchLift puts the index tip ``pad_contact - force / pad_stiffness`` [m] from the
    thumb tip along the thumb pad's normal (the glove's pinch of the bare pads); for the pen
    this gap is set to the pen's diameter + :data:`PEN_PAD_GAP` (a person whose
    ``pad_contact`` is the pen's width), so the index comes down on the pen right across from
    the thumb pad: an antipodal pinch whose squeeze passes through the pen's axis (with the
    bare-pad pinch, the pads meet at 110 degrees around the pen and squeeze it out). The
    glove still reads the real person (no pad contact, no pinch cross-talk: the pads touch
    the pen, not each other). The thumb is more opposed than in the default pinch
    (:data:`PEN_PINCH_POSES`) so that the index reaches across a 2 cm pen.
    """
    s = person.hand_scale
    wide = dataclasses.replace(person, pad_contact=2.0 * PEN_RADIUS + PEN_PAD_GAP * s)
    for cmc, flexion, dip in PEN_PINCH_POSES:
        try:
            return ReachPinchLift(wide, thumb=(cmc, flexion), dip=dip)
        except ValueError:  # out of this hand's reach: the next pose
            continue
    raise ValueError(f"no pen pinch of {PEN_PINCH_POSES} is in reach of {person.person_id}")


def _pen_position_hand(person: PersonParams) -> FloatArray:
    """Pen centre in the hand frame at zero wrist angles [m] (origin: wrist centre)."""
    pinch = pen_operator(person).poses["pinch"]
    thumb_angles = pinch[[JOINT_NAMES.index("thumb_cmc"), JOINT_NAMES.index("thumb_flexion")]]
    _, thumb = hand_points(pinch, person)
    a3 = float(thumb_directions(thumb_angles)[-1])
    normal = np.array([math.sin(a3), -math.cos(a3)])  # thumb pad normal (hand.py's -i e^{ia})
    s = person.hand_scale
    centre = thumb[-1] + (THUMB_PAD_RADIUS * s + PEN_RADIUS) * normal  # on the thumb pad
    return np.array([NOMINAL_WRIST_TO_MCP * s + centre[0], centre[1], 0.0])


class FromPreShape:
    """An operator started later: ``Θ(t) = operator(t + start)`` [rad], t [s].

    The episodes of :class:`GloveGraspEnv` begin when the scripted reach has pre-shaped the
    hand (thumb under the pen, index above it): in the glove's planar hand the thumb's
    opposition swing passes through the place of the pinch, so a pen already lying there
    would be struck (see HUMAN_HAND.md).
    """

    def __init__(self, operator: ReachPinchLift, start: float | None = None) -> None:
        self.operator = operator
        self.start = operator.timings.reach if start is None else float(start)

    def __call__(self, t: float) -> FloatArray:
        return self.operator(t + self.start)


def load_glove_scene(person: PersonParams | None = None) -> mujoco.MjModel:
    """Compile the glove scene for ``person``'s hand (default: the nominal hand).

    The hand of ``human_hand.xml`` (nominal adult) is rescaled with :class:`mujoco.MjSpec`:
    index and thumb segments get the person's lengths [m] (``index_lengths``,
    ``thumb_lengths``), the thumb's CMC its ``thumb_base``, everything else (palm, radii,
    other fingers) scales with ``hand_scale``. The pen is put where this person's pen pinch
    (:func:`pen_operator`) closes, on the thumb pad, resting in the cradles of two posts.

    Raises:
        ValueError: no pen pinch of :data:`PEN_PINCH_POSES` is in reach of this hand.
    """
    person = person if person is not None else PersonParams.nominal()
    s = person.hand_scale
    resource = importlib.resources.files("ias_gym.assets") / SCENE_FILE
    with importlib.resources.as_file(resource) as path:
        spec = mujoco.MjSpec.from_file(str(path))

    hand = spec.body("hand")
    for body in hand.find_all(mujoco.mjtObj.mjOBJ_BODY):
        body.pos = np.asarray(body.pos) * s
    for geom in hand.find_all(mujoco.mjtObj.mjOBJ_GEOM):
        geom.size = np.asarray(geom.size) * s
        geom.fromto = np.asarray(geom.fromto) * s
    for site in hand.find_all(mujoco.mjtObj.mjOBJ_SITE):
        site.pos = np.asarray(site.pos) * s

    def segment(geom: str, length: float, child: str | None, site: str | None) -> None:
        spec.geom(geom).fromto = [0.0, 0.0, 0.0, length, 0.0, 0.0]
        if child is not None:
            spec.body(child).pos = [length, 0.0, 0.0]
        if site is not None:
            spec.site(site).pos = [length, 0.0, 0.0]

    l1, l2, l3 = person.index_lengths
    segment("index_proximal", l1, "index_middle", None)
    segment("index_middle", l2, "index_distal", None)
    segment("index_distal", l3, None, "index_tip")
    t1, t2, t3 = person.thumb_lengths
    segment("thumb_metacarpal", t1, "thumb_proximal", None)
    segment("thumb_proximal", t2, "thumb_distal", None)
    segment("thumb_distal", t3, None, "thumb_tip")
    for pad, length in (("index_pad", l3), ("thumb_pad", t3)):
        # across the fingertip, PAD_AT of the distal phalanx out (scaled half width)
        geom = spec.geom(pad)
        half = geom.fromto[5]
        geom.fromto = [PAD_AT * length, 0.0, -half, PAD_AT * length, 0.0, half]
    mcp = NOMINAL_WRIST_TO_MCP * s
    spec.body("index_proximal").pos = [mcp, 0.0, 0.0]
    spec.body("thumb_metacarpal").pos = [mcp + person.thumb_base[0], person.thumb_base[1], 0.0]

    # The pen where this hand's pinch closes, resting on the support.
    forearm = spec.body("forearm")
    frame = forearm_frame(FOREARM_PITCH)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, frame.ravel())
    forearm.quat = quat
    c, s_ = math.cos(PINCH_WRIST_FLEXION), math.sin(PINCH_WRIST_FLEXION)
    wrist = np.array([[c, -s_, 0.0], [s_, c, 0.0], [0.0, 0.0, 1.0]])
    pen_world = np.asarray(forearm.pos) + frame @ wrist @ _pen_position_hand(person)
    spec.body("pen").pos = pen_world
    rods = pen_world[2] - math.sqrt((PEN_RADIUS + ROD_RADIUS) ** 2 - ROD_SPACING**2)
    for name, side in (("left", -1.0), ("right", 1.0)):
        post = spec.geom(f"support_{name}")
        post.size = [POST_HALF_WIDTH, POST_HALF_WIDTH, rods / 2.0]
        post.pos = [side * POST_OFFSET, pen_world[1], rods / 2.0]
        for rod, dy in (("a", -ROD_SPACING), ("b", ROD_SPACING)):
            spec.geom(f"cradle_{name}_{rod}").pos = [side * POST_OFFSET, pen_world[1] + dy, rods]
    return spec.compile()


def _cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    path = Path(base) / "ias_gym" / "glove_profiles"
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:  # read-only home: a temp dir
        path = Path(tempfile.gettempdir()) / "ias_gym_glove_profiles"
        path.mkdir(parents=True, exist_ok=True)
    return path


def default_calibration(person: PersonParams) -> Calibration:
    """The ANN calibration of a simulated ``person``, trained once and cached as a profile.

    The profile lives in ``$XDG_CACHE_HOME/ias_gym/glove_profiles`` (``~/.cache/...``) as
    ``<person_id>-seed<seed>.json``; training (the first time) needs torch (the ``[glove]``
    extra) and takes seconds.

    Raises:
        InputError: the person's id is not a valid id (it names the cache file; see
            :func:`~ias_gym.glove.ids.check_id`), checked before any file is touched.
    """
    name = f"{check_id(person.person_id, 'person_id')}-seed{int(person.seed)}.json"
    path = _cache_dir() / name
    if path.exists():
        try:
            return load_profile(path, person_id=person.person_id).calibration
        except ProfileError:
            pass  # stale or damaged: train again
    from ias_gym.glove.training import calibrate_person  # torch, on first use only

    run = calibrate_person(person)
    save_profile(run.profile, path)
    return run.profile.calibration


@dataclasses.dataclass(frozen=True)
class GloveGraspConfig:
    """Settings of :class:`GloveGraspEnv` (units in the comments)."""

    person_id: str = "p1"  # simulated person wearing the glove (PersonParams.sample)
    control_dt: float = 0.01  # one env step = one glove read [s]; a multiple of 1 ms
    duration: float = 4.0  # episode length [s] (registered max_episode_steps = 400)
    action_scale: float = 0.2  # joint offset of a full action [rad]
    filter_tau: float = 0.05  # time constant of the low-pass on the calibrated Θ [s]; 0: off
    lift_height: float = 0.03  # success: pen centre this much above its start [m]
    drop_height: float = 0.05  # terminated: pen centre this far below its start [m]
    max_distance: float = 0.15  # terminated: pen centre this far from its start [m]
    lift_weight: float = 1.0  # weight of the lift term [-]
    contact_weight: float = 0.5  # weight of the pinch-contact term [-]
    effort_weight: float = 0.1  # weight of the action-effort penalty [-]

    def __post_init__(self) -> None:
        # person_id names the cached profile file: checked before anything is built.
        check_id(self.person_id, "person_id")
        if self.control_dt <= 0 or self.duration <= 0:
            raise ValueError("control_dt and duration must be positive [s]")


#: ``info["fault"]`` when the calibration turns the glove's readings into NaN or inf (a
#: broken calibration): the step keeps the last finite targets and ends the episode.
NONFINITE_THETA_FAULT = "calibration gave non-finite joint angles (check the glove profile)"

#: Reward term names (info keys ``reward_<name>``).
REWARD_TERMS = ("lift", "pinch", "effort")


class GloveGraspEnv(gym.Env[FloatArray, NDArray[np.float32]]):
    """The glove-driven human hand pinches the pen and lifts it (``IAS-GloveGrasp-v0``).

    Every step reads the glove (Ψ [rad]), calibrates it (Θ = f(Ψ) [rad]), low-passes it
    (``filter_tau``) and sets the hand's position targets to Θ + ``action_scale`` x action,
    clipped to the joint ranges. With zero
    action the env is pure teleoperation; the default glove is the simulated person
    ``person_id`` running the pen pinch (:func:`pen_operator`, a
    :class:`~ias_gym.glove.device.ReachPinchLift`) from its pre-shape (:class:`FromPreShape`):
    close the pinch (0.7 s), hold (0.5 s), lift by extending the wrist (1 s), hold.

    Action:
        ``Box(-1, 1, (10,))``: offsets of the 10 joint targets in the order of
        :data:`~ias_gym.glove.hand.JOINT_NAMES`, times ``action_scale`` [rad]. Values outside
        [-1, 1] are clipped; NaN or inf raise ``ValueError``.

    Observation (``(39,)`` float64):
        hand joint angles (10) [rad] and velocities (10) [rad/s] (JOINT_NAMES order), pen
        centre relative to its start (3) [m], pen orientation quaternion (4), pen linear (3)
        [m/s] and angular (3) [rad/s] velocity (world frame), force-display torques on
        :data:`~ias_gym.glove.device.ACTUATED_JOINTS` (5) [N m], episode time (1) [s].

    Reward:
        sum of ``lift = lift_weight * clip(dz / lift_height, 0, 1)`` (dz: pen height gain [m]),
        ``pinch = contact_weight`` while both index and thumb touch the pen (else 0), and
        ``effort = -effort_weight * mean(action^2)``; each is in ``info["reward_<name>"]``.

    Termination:
        terminated when the pen falls ``drop_height`` below its start or leaves
        ``max_distance`` of it; truncated at ``duration`` (also by the registered
        ``max_episode_steps``), when the glove reports a fault (``info["fault"]`` says
        which, e.g. a CAN watchdog trip, or :data:`NONFINITE_THETA_FAULT` when the
        calibration turns readings into NaN or inf, whose targets never reach MuJoCo: the
        last finite ones are kept; ``""`` otherwise), or when the simulation diverges
        (``info["sim_unstable"]``: MuJoCo raised a warning, e.g. a huge acceleration, or
        the state is not finite; the state is then put back to the start, not
        terminated). ``info["is_success"]``: pen >= ``lift_height`` above its start and
        touching neither the support nor the floor.

    Force display: the contact forces of the pen on the index and thumb geoms, f [N], give
    ``tau = J^T f`` [N m] on the actuated joints (MuJoCo Jacobians at the contact points; the
    thumb's coupled MCP/IP hinges fold into thumb_flexion), in the observation, in
    ``info["feedback_torques"]`` and written to the glove (``write_feedback``, saturated there).

    Version history:
        v0: first version.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 100}  # noqa: RUF012

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        person: PersonParams | None = None,
        calibration: Calibration | None = None,
        glove_factory: Callable[[int], GloveDevice] | None = None,
        **config: Any,
    ) -> None:
        """Build the env.

        Args:
            render_mode: ``None`` or ``"rgb_array"``.
            person: the hand's owner (default: ``PersonParams.sample(config.person_id)``).
            calibration: Θ = f(Ψ) of that person (default: :func:`default_calibration`).
            glove_factory: ``seed -> GloveDevice`` called at every reset (a stream of
                readings per episode). Default: a :class:`SimulatedGlove` (seeded noise) on
                the person running :class:`FromPreShape` of :class:`ReachPinchLift`.
            **config: fields of :class:`GloveGraspConfig` to override.
        """
        fields = {f.name for f in dataclasses.fields(GloveGraspConfig)}
        unknown = sorted(set(config) - fields)
        if unknown:
            raise TypeError(f"unknown config {unknown}; known: {sorted(fields)}")
        self.config = GloveGraspConfig(**config)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise InputError(
                f"render_mode {render_mode!r} is not one of {self.metadata['render_modes']}"
                + ("; there is no window viewer, use rgb_array" if render_mode == "human" else "")
            )
        self.render_mode = render_mode
        self.person = person if person is not None else PersonParams.sample(self.config.person_id)
        self.calibration = (
            calibration if calibration is not None else default_calibration(self.person)
        )
        if glove_factory is None:
            person_ = self.person

            def glove_factory(seed: int) -> GloveDevice:
                return SimulatedGlove(person_, FromPreShape(pen_operator(person_)), seed)

        self.glove_factory = glove_factory
        self.glove: GloveDevice | None = None

        m = self.model = load_glove_scene(self.person)
        self.data = mujoco.MjData(m)
        self.frame_skip = round(self.config.control_dt / m.opt.timestep)
        if self.frame_skip < 1 or not math.isclose(
            self.frame_skip * m.opt.timestep, self.config.control_dt
        ):
            raise ValueError(f"control_dt must be a multiple of {m.opt.timestep} s")
        self.max_steps = round(self.config.duration / self.config.control_dt)
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.config.control_dt)}

        # Names looked up once (STYLE.md).
        joints = [m.joint(n).id for n in JOINT_NAMES]
        self._qadr = m.jnt_qposadr[joints].copy()
        self._vadr = m.jnt_dofadr[joints].copy()
        self._act = np.array([m.actuator(n).id for n in JOINT_NAMES])
        self._ctrl_lo = m.actuator_ctrlrange[self._act, 0].copy()
        self._ctrl_hi = m.actuator_ctrlrange[self._act, 1].copy()
        self._coupled_q = [m.jnt_qposadr[m.joint(n).id] for n in ("thumb_mcp_share", "thumb_ip")]
        self._flex = JOINT_NAMES.index("thumb_flexion")
        self._fb_dofs = np.array([m.jnt_dofadr[m.joint(n).id] for n in ACTUATED_JOINTS])
        self._fb_flex = ACTUATED_JOINTS.index("thumb_flexion")
        self._coupled_dofs = np.array(
            [m.jnt_dofadr[m.joint(n).id] for n in ("thumb_mcp_share", "thumb_ip")]
        )
        self._pen_body = m.body("pen").id
        self._pen_q = m.jnt_qposadr[m.joint("pen").id]
        self._pen_v = m.jnt_dofadr[m.joint("pen").id]
        self._pen_geom = m.geom("pen").id
        self._index_geoms = {m.geom(n).id for n in INDEX_GEOMS}
        self._thumb_geoms = {m.geom(n).id for n in THUMB_GEOMS}
        self._rest_geoms = {m.geom(n).id for n in SUPPORT_GEOMS}
        self._pen_start = np.zeros(3)
        self._warnings = self.data.warning.number  # a view: MuJoCo's warning counters
        self._unstable = False
        self._fault = ""  # latched for the episode: a broken calibration stays broken
        self._jac = np.zeros((3, m.nv))
        self._force6 = np.zeros(6)

        self.action_space = spaces.Box(-1.0, 1.0, shape=(len(JOINT_NAMES),), dtype=np.float32)
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(39,), dtype=np.float64)
        self._steps = 0
        cfg = self.config
        self._alpha = cfg.control_dt / (cfg.filter_tau + cfg.control_dt)
        self._theta = np.zeros(len(JOINT_NAMES))
        self._feedback = np.zeros(len(ACTUATED_JOINTS))
        self._touch = (False, False)
        self._pinch_force = 0.0
        self._renderer: Any = None

    # ------------------------------------------------------------------ glove
    def _open_glove(self, seed: int) -> GloveDevice:
        """The glove of a new episode: a fresh device from ``glove_factory`` (the previous
        one closed), armed with :meth:`~GloveDevice.enable`."""
        if self.glove is not None:
            self.glove.close()
        glove = self.glove_factory(seed)
        glove.enable()
        return glove

    def _read_theta(self, fallback: FloatArray) -> tuple[FloatArray, bool]:
        """Calibrated joint angles Θ [rad] of a new reading, clipped to the joint ranges, and
        whether the calibration gave finite numbers.

        NaN passes ``np.clip`` and would reach MuJoCo's ``ctrl`` (which then warns and
        zeroes it, so the hand goes limp without a word): non-finite entries are replaced
        by ``fallback`` (the last finite targets) and reported.
        """
        assert self.glove is not None
        theta = np.asarray(self.calibration.predict(self.glove.read().psi), dtype=np.float64)
        finite = np.isfinite(theta)
        ok = bool(finite.all())
        if not ok:
            theta = np.where(finite, theta, fallback)
        return np.clip(theta, JOINT_LOW, JOINT_HIGH), ok

    def _place_hand(self, theta: FloatArray) -> None:
        """Reset MuJoCo's state: hand at ``theta`` [rad] and at rest, pen at its start."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[self._qadr] = theta
        d.qpos[self._coupled_q] = THUMB_IP_RATIO_SHARE * theta[self._flex]
        d.ctrl[self._act] = theta
        mujoco.mj_forward(m, d)

    # ------------------------------------------------------------------ physics
    def _force_display(self) -> tuple[FloatArray, tuple[bool, bool], float, bool]:
        """(tau on ACTUATED_JOINTS [N m], (index, thumb) touch, pinch normal force [N],
        pen touches the support or floor)."""
        m, d = self.model, self.data
        tau_dof = np.zeros(m.nv)
        touch_i = touch_t = rest = False
        normal = 0.0
        for k in range(d.ncon):
            c = d.contact[k]
            g1, g2 = int(c.geom1), int(c.geom2)
            if self._pen_geom not in (g1, g2):
                continue
            other = g2 if g1 == self._pen_geom else g1
            if other in self._rest_geoms:
                rest = True
                continue
            is_index = other in self._index_geoms
            if not (is_index or other in self._thumb_geoms):
                continue
            mujoco.mj_contactForce(m, d, k, self._force6)
            # Force of geom1 on geom2 in the contact frame (rows normal, t1, t2) -> world.
            f_world = c.frame.reshape(3, 3).T @ self._force6[:3]
            f_finger = f_world if other == g2 else -f_world  # the pen's force on the finger
            mujoco.mj_jac(m, d, self._jac, None, c.pos, int(m.geom_bodyid[other]))
            tau_dof += self._jac.T @ f_finger
            normal += float(self._force6[0])
            touch_i |= is_index
            touch_t |= not is_index
        tau = tau_dof[self._fb_dofs].copy()
        # thumb_flexion drives the coupled MCP-share and IP hinges (0.45 each): virtual work.
        tau[self._fb_flex] += THUMB_IP_RATIO_SHARE * float(tau_dof[self._coupled_dofs].sum())
        return tau, (touch_i, touch_t), normal, rest

    def _observation(self) -> FloatArray:
        d = self.data
        pen_v = d.qvel[self._pen_v : self._pen_v + 6]
        # Free joint: linear velocity in world, angular velocity in the body frame -> world.
        omega = d.xmat[self._pen_body].reshape(3, 3) @ pen_v[3:6]
        return np.concatenate(
            [
                d.qpos[self._qadr],
                d.qvel[self._vadr],
                d.xpos[self._pen_body] - self._pen_start,
                d.xquat[self._pen_body],
                pen_v[0:3],
                omega,
                self._feedback,
                [self._steps * self.config.control_dt],
            ]
        )

    def _info(self, terms: dict[str, float], rest: bool, fault: str) -> dict[str, Any]:
        dz = float(self.data.xpos[self._pen_body][2] - self._pen_start[2])
        return {
            "fault": fault,
            "sim_unstable": self._unstable,
            **{f"reward_{k}": v for k, v in terms.items()},
            "is_success": bool(dz >= self.config.lift_height and not rest),
            "pen_height": dz,
            "feedback_torques": self._feedback.copy(),
            "pinch_force": self._pinch_force,
            "index_contact": self._touch[0],
            "thumb_contact": self._touch[1],
        }

    def _rewards(self, action: FloatArray) -> dict[str, float]:
        cfg = self.config
        dz = float(self.data.xpos[self._pen_body][2] - self._pen_start[2])
        return {
            "lift": cfg.lift_weight * min(max(dz / cfg.lift_height, 0.0), 1.0),
            "pinch": cfg.contact_weight * float(all(self._touch)),
            "effort": -cfg.effort_weight * float(np.mean(action * action)),
        }

    def episode_metrics(self, info: dict[str, Any]) -> dict[str, float]:
        """The task's measures of a finished episode, from its last ``info``: the pen's
        final height above its start [m] and the pads' normal force on it [N]."""
        return {"pen_height": float(info["pen_height"]), "pinch_force": float(info["pinch_force"])}

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[FloatArray, dict[str, Any]]:
        super().reset(seed=seed)
        self.glove = self._open_glove(int(self.np_random.integers(2**31)))
        rest_pose = np.clip(np.zeros(len(JOINT_NAMES)), JOINT_LOW, JOINT_HIGH)
        theta, ok = self._read_theta(rest_pose)
        self._theta = theta
        self._fault = "" if ok else NONFINITE_THETA_FAULT  # the first step ends the episode
        self._unstable = False
        self._place_hand(theta)
        self._pen_start = self.data.xpos[self._pen_body].copy()
        self._steps = 0
        self._feedback, self._touch, self._pinch_force, rest = self._force_display()
        self.glove.write_feedback(self._feedback)  # the force display starts with the episode
        terms = dict.fromkeys(REWARD_TERMS, 0.0)
        return self._observation(), self._info(terms, rest, self._fault)

    def step(self, action: NDArray[Any]) -> tuple[FloatArray, float, bool, bool, dict[str, Any]]:
        if self.glove is None:
            raise RuntimeError("call reset() before step()")
        a = np.asarray(action, dtype=np.float64)
        if a.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape}, got {a.shape}")
        if not np.isfinite(a).all():
            raise ValueError(f"action contains NaN or inf: {a.tolist()}; actions must be finite")
        a = np.clip(a, -1.0, 1.0)
        # Low-pass the calibrated angles: the sensor noise, amplified by the calibration,
        # would shake the fingers at the glove's rate and shake the pen loose.
        theta, ok = self._read_theta(self._theta)
        self._theta += self._alpha * (theta - self._theta)
        if not ok and not self._fault:
            self._fault = NONFINITE_THETA_FAULT
        fault = self.glove.fault or self._fault
        target = self._theta + self.config.action_scale * a  # finite: theta and a are
        m, d = self.model, self.data
        d.ctrl[self._act] = np.clip(target, self._ctrl_lo, self._ctrl_hi)
        warnings_before = int(self._warnings.sum())
        mujoco.mj_step(m, d, self.frame_skip)
        self._steps += 1
        # A diverging simulation makes MuJoCo warn (and reset its data), as in the pen
        # tasks (PenHandEnv.step); a state that is not finite is put back to the start.
        finite = bool(np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all())
        self._unstable = int(self._warnings.sum()) > warnings_before or not finite
        if not finite:
            self._place_hand(self._theta)
        self._feedback, self._touch, self._pinch_force, rest = self._force_display()
        self.glove.write_feedback(self._feedback)

        terms = self._rewards(a)
        reward = float(sum(terms.values()))
        offset = self.data.xpos[self._pen_body] - self._pen_start
        cfg = self.config
        terminated = not self._unstable and bool(
            offset[2] < -cfg.drop_height or float(np.linalg.norm(offset)) > cfg.max_distance
        )
        truncated = self._steps >= self.max_steps or bool(fault) or self._unstable
        return self._observation(), reward, terminated, truncated, self._info(terms, rest, fault)

    def render(self) -> NDArray[np.uint8] | None:
        """The scene from the ``perspective`` camera as ``(360, 480, 3)`` RGB, or ``None``
        without ``render_mode="rgb_array"``."""
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            self._renderer = mujoco.Renderer(self.model, 360, 480)
        self._renderer.update_scene(self.data, camera="perspective")
        return np.asarray(self._renderer.render())

    def __getstate__(self) -> dict[str, Any]:
        """Refuse clearly: the env holds a live glove device (simulated or real)."""
        raise TypeError(
            "IAS-GloveGrasp-v0 holds a live glove device and cannot be pickled; build a new "
            "env with the same glove_factory and calibration instead"
        )

    def close(self) -> None:
        if self.glove is not None:
            self.glove.close()
            self.glove = None
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

"""The glove's virtual world: ``scene_glove.xml`` compiled for one person's hand.

``scene_glove.xml`` = ``human_hand.xml`` (the hand the glove drives) + ``pen.xml`` + two posts
with cradles that the pen rests on. :func:`load_glove_scene` rescales the hand with
:class:`mujoco.MjSpec` to the person's segment lengths and puts the pen where that person's
pen pinch (:func:`~ias_gym.glove.operator.pen_operator`) closes. The scene's own numbers (the
pen's radius, the pads' and rods' radii, the wrist-to-MCP distance, the thumb's coupling) are
read from the spec or the compiled model, never copied here.
"""

from __future__ import annotations

import importlib.resources
import math

import mujoco
import numpy as np
from numpy.typing import NDArray

from ias_gym.glove.device import ReachPinchLift
from ias_gym.glove.hand import JOINT_NAMES, PersonParams, hand_points, thumb_directions
from ias_gym.glove.operator import pen_operator
from ias_gym.sim.scene_constants import glove_pen_radius

FloatArray = NDArray[np.float64]

SCENE_FILE = "scene_glove.xml"
#: The two posts the pen rests on: half width [m], distance of each from the pen's middle
#: along the pen [m] (the thumb passes between them).
POST_HALF_WIDTH = 0.006
POST_OFFSET = 0.04
#: Half the spacing of the cradle rods on each post, across the pen [m].
ROD_SPACING = 0.006
#: The pinch pose's wrist flexion [rad] (ReachPinchLift's open/pinch wrist angle).
PINCH_WRIST_FLEXION = -0.1
#: Forearm pitch [rad]: the fingers point down by this much at zero wrist angles, so that the
#: thumb, under the pen, still slopes down distally when the wrist extends to lift.
FOREARM_PITCH = 0.3
#: Names of the hand's geoms whose pen contacts make up each finger's contact (the force
#: display and the skill model's columns).
INDEX_GEOMS = ("index_proximal", "index_middle", "index_distal", "index_pad")
THUMB_GEOMS = ("thumb_metacarpal", "thumb_proximal", "thumb_distal", "thumb_pad")
#: The skill model's fingers in column order -> their geoms; their tip sites; which comes
#: down on the pen from above in the pinch (the index; the thumb is under the pen).
FINGER_GEOMS: dict[str, tuple[str, ...]] = {"index": INDEX_GEOMS, "thumb": THUMB_GEOMS}
FINGER_TIPS = ("index_tip", "thumb_tip")
FINGER_ABOVE = (True, False)
#: Geoms the pen rests on before the lift.
SUPPORT_GEOMS = (
    "floor",
    "support_left",
    "support_right",
    *(f"cradle_{side}_{rod}" for side in ("left", "right") for rod in ("a", "b")),
)
#: Where the pad capsules sit along the distal phalanges (fraction of the length).
PAD_AT = 0.75
#: The hand joint that drives the thumb's passive hinges (equalities of human_hand.xml).
THUMB_DRIVER = "thumb_flexion"


def forearm_frame(pitch: float) -> FloatArray:
    """Rotation world <- hand frame at zero wrist angles: palm down, fingers along world +y
    tilted down by ``pitch`` [rad]; the hand's z (flexion axis) is along world -x."""
    x = np.array([0.0, math.cos(pitch), -math.sin(pitch)])
    y = np.array([0.0, -math.sin(pitch), -math.cos(pitch)])
    return np.column_stack([x, y, np.cross(x, y)])


def _scene_spec() -> mujoco.MjSpec:
    resource = importlib.resources.files("ias_gym.assets") / SCENE_FILE
    # The scene includes human_hand.xml and pen.xml by relative path: parse it from disk.
    with importlib.resources.as_file(resource) as path:
        return mujoco.MjSpec.from_file(str(path))


def scene_operator(person: PersonParams) -> ReachPinchLift:
    """:func:`~ias_gym.glove.operator.pen_operator` for the glove scene's pen.

    Raises:
        ValueError: no pen pinch is in reach of ``person``'s hand.
    """
    return pen_operator(person, glove_pen_radius())


def pen_position_hand(
    operator: ReachPinchLift, person: PersonParams, wrist_to_mcp: float, offset: float
) -> FloatArray:
    """Pen centre in the hand frame at zero wrist angles [m] (origin: wrist centre).

    Args:
        operator: the person's pen pinch (its ``pinch`` pose places the thumb).
        person: the hand.
        wrist_to_mcp: wrist centre to index MCP along the metacarpal, this hand's [m].
        offset: thumb pad radius + pen radius [m]: the pen lies on the thumb pad.
    """
    pinch = operator.poses["pinch"]
    thumb_angles = pinch[[JOINT_NAMES.index("thumb_cmc"), JOINT_NAMES.index("thumb_flexion")]]
    _, thumb = hand_points(pinch, person)
    a3 = float(thumb_directions(thumb_angles)[-1])
    normal = np.array([math.sin(a3), -math.cos(a3)])  # thumb pad normal (hand.py's -i e^{ia})
    centre = thumb[-1] + offset * normal  # on the thumb pad
    return np.array([wrist_to_mcp + centre[0], centre[1], 0.0])


def load_glove_scene(person: PersonParams | None = None) -> mujoco.MjModel:
    """Compile the glove scene for ``person``'s hand (default: the nominal hand).

    The hand of ``human_hand.xml`` (nominal adult) is rescaled with :class:`mujoco.MjSpec`:
    index and thumb segments get the person's lengths [m] (``index_lengths``,
    ``thumb_lengths``), the thumb's CMC its ``thumb_base``, everything else (palm, radii,
    other fingers) scales with ``hand_scale``. The pen is put where this person's pen pinch
    (:func:`scene_operator`) closes, on the thumb pad, resting in the cradles of two posts.

    Args:
        person: the hand's owner.

    Raises:
        ValueError: no pen pinch of :data:`~ias_gym.glove.operator.PEN_PINCH_POSES` is in
            reach of this hand.
    """
    person = person if person is not None else PersonParams.nominal()
    s = person.hand_scale
    spec = _scene_spec()

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
    # The index MCP as the XML has it (scaled above): the metacarpal's length.
    mcp = float(spec.body("index_proximal").pos[0])
    spec.body("thumb_metacarpal").pos = [mcp + person.thumb_base[0], person.thumb_base[1], 0.0]

    # The pen where this hand's pinch closes, resting on the support.
    pen_radius = float(spec.geom("pen").size[0])
    thumb_pad_radius = float(spec.geom("thumb_pad").size[0])  # scaled above
    rod_radius = float(spec.geom("cradle_left_a").size[0])  # the four rods are alike
    operator = pen_operator(person, pen_radius)
    forearm = spec.body("forearm")
    frame = forearm_frame(FOREARM_PITCH)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, frame.ravel())
    forearm.quat = quat
    c, s_ = math.cos(PINCH_WRIST_FLEXION), math.sin(PINCH_WRIST_FLEXION)
    wrist = np.array([[c, -s_, 0.0], [s_, c, 0.0], [0.0, 0.0, 1.0]])
    pen_hand = pen_position_hand(operator, person, mcp, thumb_pad_radius + pen_radius)
    pen_world = np.asarray(forearm.pos) + frame @ wrist @ pen_hand
    spec.body("pen").pos = pen_world
    rods = pen_world[2] - math.sqrt((pen_radius + rod_radius) ** 2 - ROD_SPACING**2)
    for name, side in (("left", -1.0), ("right", 1.0)):
        post = spec.geom(f"support_{name}")
        post.size = [POST_HALF_WIDTH, POST_HALF_WIDTH, rods / 2.0]
        post.pos = [side * POST_OFFSET, pen_world[1], rods / 2.0]
        for rod, dy in (("a", -ROD_SPACING), ("b", ROD_SPACING)):
            spec.geom(f"cradle_{name}_{rod}").pos = [side * POST_OFFSET, pen_world[1] + dy, rods]
    return spec.compile()


def thumb_coupling(model: mujoco.MjModel) -> tuple[NDArray[np.int64], FloatArray]:
    """The thumb's passive hinges and their ratios to :data:`THUMB_DRIVER`, from the model.

    ``human_hand.xml`` couples ``thumb_mcp_share`` and ``thumb_ip`` to ``thumb_flexion`` by
    joint equalities ``q_i = ratio_i * q_flexion`` (``polycoef = 0 ratio 0 0 0``).

    Args:
        model: a compiled glove scene.

    Returns:
        ``(joints, ratios)``: ids of the coupled joints and their ratios [-].

    Raises:
        ValueError: a joint equality on the driver is not linear through zero, or there is
            none.
    """
    driver = model.joint(THUMB_DRIVER).id
    joints, ratios = [], []
    for e in range(model.neq):
        if int(model.eq_type[e]) != int(mujoco.mjtEq.mjEQ_JOINT) or model.eq_obj2id[e] != driver:
            continue
        poly = model.eq_data[e, :5]
        if poly[0] != 0.0 or np.any(poly[2:] != 0.0):
            raise ValueError(f"equality {e} couples the thumb non-linearly: polycoef {poly}")
        joints.append(int(model.eq_obj1id[e]))
        ratios.append(float(poly[1]))
    if not joints:
        raise ValueError(f"no joint equality couples a hinge to {THUMB_DRIVER!r}")
    return np.array(joints, dtype=np.int64), np.array(ratios)

"""Solve an external hand's placement and grasp as a pen hand; print the constants.

The Shadow hand (``ias_gym.sim.external_hands``) and the LEAP hand
(``ias_gym.sim.leap_hand``) are fixed to the world; this script finds where: the hand
mount's pose and the nine driven joints such that

- the two top fingers' tips touch the top of the pen (Shadow: first and little finger at
  x = -3.5 and +4 cm; LEAP: index and middle finger at -2.25 and +2.25 cm) and the thumb's its
  bottom at x = 0 (every tip 0.3 mm inside the pen, as the other hands' ``grasp``
  keyframes), which fixes 9 coordinates;
- every other geom of the hand keeps ``--clearance`` from the pen (a link touching the pen is
  a contact the grasp model does not have);
- among the many placements that do both, the one whose joints lie nearest their ranges'
  middles (a margin for the motions of the pen tasks) and whose palm is nearest upright
  (the palm faces the pen, the fingers point up): small weights on both.

It is a nonlinear least-squares problem (``scipy.optimize.least_squares`` within the joint
ranges) solved from ``--starts`` random starts; the best is printed as the module's
``SHADOW_MOUNT`` and ``SHADOW_GRASP`` (``LEAP_MOUNT``, ``LEAP_GRASP``). Deterministic in
``--seed``.

    python train/place_hand.py --hand shadow
    python train/place_hand.py --hand leap
    python train/place_hand.py --hand leap --layout two-under --steepness-axis tip \
        --steepness 0.1 --thumb-steepness 0.3 --starts 6

``--layout two-under`` (LEAP only) puts the index (x = +2.25 cm) and the middle finger
(-2.25 cm) below the pen and the thumb alone on top, the mount turned so that the palm faces
up. ``--thumb-steepness`` asks the thumb's distal link for its own least cosine;
``--steepness-axis tip`` measures the cosines along the rounded tip's axis (the direction from
the capsule's base to its end) instead of the distal body's z axis, which on LEAP is not the
tip's axis (on the body's z a thumb of cosine 0.8 or 0.9 still touched the pen with its side,
1.0-1.1 mm deep instead of 0.3 mm).
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation
from tqdm import tqdm

from ias_gym.sim import external_hands, leap_hand
from ias_gym.sim.grasp_pose import place_grasp
from ias_gym.sim.pen_hand import PenHandPhysics


@dataclass(frozen=True)
class External:
    """What differs between the hands: the scene, the fingers, the coupling, the mount."""

    spec: Callable[..., mujoco.MjSpec]
    fingers: tuple[Any, ...]
    coupling: float
    mount: str
    #: The palm upright: its fingers along world +z, its palm facing +y, the first finger
    #: at -x.
    upright: Rotation
    #: Contact targets per finger: x along the pen [m] and side (+1 top, -1 bottom).
    targets: tuple[tuple[float, float], ...]
    #: The mean of the random starts' mount positions [m].
    start: tuple[float, float, float]
    prefix: str


HANDS = {
    "shadow": External(
        external_hands.shadow_spec,
        external_hands.SHADOW_FINGERS,
        external_hands.SHADOW_COUPLING,
        "shadow/robot0:hand mount",
        Rotation.from_euler("z", np.pi),
        ((-0.035, 1.0), (0.0, -1.0), (0.04, 1.0)),
        (0.0, -0.06, 0.1),
        "SHADOW",
    ),
    "leap": External(
        leap_hand.leap_spec,
        leap_hand.LEAP_FINGERS,
        leap_hand.LEAP_COUPLING,
        "leap/leap_mount",
        # the model's fingers point along its mount's +x, its palm faces +z
        Rotation.from_matrix([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]),
        ((-0.0225, 1.0), (0.0, -1.0), (0.0225, 1.0)),
        (0.0, -0.08, 0.0),
        "LEAP",
    ),
}
#: Other finger layouts per hand: index and middle finger below the pen at +2.25 and -2.25 cm,
#: the thumb on top; the palm faces up (the fingers along world +y, the index at +x).
LAYOUTS = {
    ("leap", "two-under"): {
        "upright": Rotation.from_matrix([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
        "targets": ((0.0225, -1.0), (0.0, 1.0), (-0.0225, -1.0)),
        "start": (0.0, -0.1, 0.12),
    },
}
PEN_CENTRE = np.array([0.0, 0.0, 0.2])
PEN_RADIUS = 0.01
PENETRATION = 3e-4


def _within(m: mujoco.MjModel, body: int, root: int) -> bool:
    """Whether ``body`` is ``root`` or below it in the kinematic tree."""
    while body > 0:
        if body == root:
            return True
        body = int(m.body_parentid[body])
    return False


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--hand", choices=sorted(HANDS), default="shadow", help="the hand")
    parser.add_argument("--starts", type=int, default=25, help="random starts")
    parser.add_argument("--seed", type=int, default=0, help="seed of the starts")
    parser.add_argument("--margin", type=float, default=0.05, help="joints from their limits [rad]")
    parser.add_argument(
        "--finger-gap",
        type=float,
        default=0.001,
        help="the model's finger pairs apart [m] (side by side at rest they are 2 mm apart)",
    )
    parser.add_argument("--clearance", type=float, default=0.004, help="links from the pen [m]")
    parser.add_argument(
        "--steepness",
        type=float,
        default=0.5,
        help="least cosine between each distal link and the direction its tip pushes in",
    )
    parser.add_argument(
        "--thumb-steepness",
        type=float,
        default=None,
        help="the thumb's (f2's) least cosine (default: --steepness)",
    )
    parser.add_argument(
        "--steepness-axis",
        choices=("body-z", "tip"),
        default="body-z",
        help="the distal link's axis the cosines measure: its body's z or the tip capsule's",
    )
    parser.add_argument(
        "--layout",
        choices=("default", "two-under"),
        default="default",
        help="the fingers' layout (two-under: LEAP's index and middle finger below the pen)",
    )
    parser.add_argument(
        "--tilts",
        type=float,
        nargs="*",
        default=[-0.25, 0.25],
        help="pen tilts the grasp must also reach, about the paper's z [rad]",
    )
    parser.add_argument(
        "--contact-x",
        type=float,
        nargs=3,
        default=None,
        help="contact positions along the pen per finger [m] (default: the hand's)",
    )
    args = parser.parse_args()
    hand = HANDS[args.hand]
    if args.layout != "default":
        if (args.hand, args.layout) not in LAYOUTS:
            parser.error(f"no layout {args.layout!r} for the hand {args.hand!r}")
        hand = dataclasses.replace(hand, **LAYOUTS[args.hand, args.layout])
    if args.contact_x is None:
        args.contact_x = [x for x, _ in hand.targets]
    sides = [side for _, side in hand.targets]
    fingers, coupling, UPRIGHT = hand.fingers, hand.coupling, hand.upright

    scene = hand.spec(grasp=None)
    scene.body(hand.mount).add_freejoint(name="mount")
    m = scene.compile()
    d = mujoco.MjData(m)
    mount = m.joint("mount").qposadr[0]
    pen = m.joint("pen").qposadr[0]
    names = [f"{f.name}_{j}" for f in fingers for j in ("abd", "mcp", "pip")]
    qadr = np.array([m.joint(n).qposadr[0] for n in names])
    lo, hi = m.jnt_range[[m.joint(n).id for n in names]].T
    dips = [
        (m.joint(f"{f.name}_dip").qposadr[0], m.joint(f"{f.name}_pip").qposadr[0])
        for f in fingers
        if f.dip is not None
    ]
    tips = [m.site(f"{f.name}_tip").id for f in fingers]
    tip_geoms = {m.geom(f"{f.name}_tip_collision").id for f in fingers}
    pen_geom = m.geom("pen").id
    hand_geoms = [
        g
        for g in range(m.ngeom)
        if m.geom_contype[g]
        and m.geom_bodyid[g] not in (0, m.geom_bodyid[pen_geom])
        and g not in tip_geoms
    ]
    order = [m.geom(f"{f.name}_tip_collision").id for f in fingers]
    radius = m.geom_size[order, 0]
    # the pen's poses the grasp must reach: at rest and tilted about the paper's z (MuJoCo
    # -y) by each of --tilts, one set of finger joints per pose, one hand placement for all
    tilts = [0.0, *args.tilts]
    local = np.array(
        [
            [x, 0.0, side * (PEN_RADIUS + r - PENETRATION)]
            for x, side, r in zip(args.contact_x, sides, radius, strict=True)
        ]
    )
    targets = [PEN_CENTRE + local @ Rotation.from_euler("y", -t).as_matrix().T for t in tilts]
    pen_quats = [Rotation.from_euler("y", -t).as_quat()[[3, 0, 1, 2]] for t in tilts]
    # the model's finger-finger contact pairs (a finger held still stands beside one moving)
    pairs = list(zip(m.pair_geom1, m.pair_geom2, strict=True))
    if not pairs:  # no explicit pairs (LEAP): every geom of one finger against the others'
        chains = []
        for f in fingers:
            base = min(m.jnt_bodyid[m.joint(f"{f.name}_{j}").id] for j in ("abd", "mcp", "pip"))
            inside = {b for b in range(m.nbody) if _within(m, b, base)}
            chains.append([g for g in hand_geoms + sorted(tip_geoms) if m.geom_bodyid[g] in inside])
        pairs = [
            (a, b) for i, c in enumerate(chains) for c2 in chains[i + 1 :] for a in c for b in c2
        ]
    fromto = np.zeros(6)
    n = len(names)

    def pose(x: np.ndarray, i: int) -> None:
        """The hand placement of x and its finger joints for pen pose i."""
        d.qpos[mount : mount + 3] = x[:3]
        w = (Rotation.from_rotvec(x[3:6]) * UPRIGHT).as_quat()  # x y z w
        d.qpos[mount + 3 : mount + 7] = [w[3], w[0], w[1], w[2]]
        d.qpos[qadr] = x[6 + n * i : 6 + n * (i + 1)]
        for dip, pip in dips:
            d.qpos[dip] = coupling * d.qpos[pip]
        d.qpos[pen : pen + 7] = [*PEN_CENTRE, *pen_quats[i]]
        mujoco.mj_kinematics(m, d)

    distal = [m.geom(f"{f.name}_tip_collision").bodyid[0] for f in fingers]
    push = -np.array(sides)  # the world z component of the direction each tip pushes in
    steepness = np.full(len(fingers), args.steepness)
    if args.thumb_steepness is not None:
        steepness[[f.name for f in fingers].index("f2")] = args.thumb_steepness
    tip_geoms_ordered = np.array(order)

    def cosines() -> np.ndarray:
        """Each distal link's axis along the direction its tip pushes in (world z)."""
        if args.steepness_axis == "tip":  # the capsule's z: from its base to its end
            return d.geom_xmat[tip_geoms_ordered, 8] * push
        return d.xmat[distal, 8] * push  # the distal body's z

    def residual(x: np.ndarray) -> np.ndarray:
        out = [0.05 * x[3:6]]
        for i in range(len(tilts)):
            pose(x, i)
            q = x[6 + n * i : 6 + n * (i + 1)]
            out.append(30.0 * (d.site_xpos[tips] - targets[i]).ravel())
            # each distal link points into the pen (its end presses it), not across it
            out.append(3.0 * np.maximum(0.0, steepness - cosines()))
            out.append(0.02 * (q - 0.5 * (lo + hi)) / (hi - lo))
            gaps = [mujoco.mj_geomDistance(m, d, g, pen_geom, 0.02, fromto) for g in hand_geoms]
            out.append(30.0 * np.maximum(0.0, args.clearance - np.array(gaps)))
            gaps = [mujoco.mj_geomDistance(m, d, a, b, 0.02, fromto) for a, b in pairs]
            out.append(30.0 * np.maximum(0.0, args.finger_gap - np.array(gaps)))
        return np.concatenate(out)

    rng = np.random.default_rng(args.seed)
    k = len(tilts)
    lower = np.r_[[-0.3] * 3, [-1.4] * 3, np.tile(lo + args.margin, k)]
    upper = np.r_[[0.3] * 3, [1.4] * 3, np.tile(hi - args.margin, k)]
    best = None
    for _ in tqdm(range(args.starts), desc="starts"):
        x0 = np.r_[
            np.clip(np.array(hand.start) + rng.normal(0, 0.05, 3), -0.29, 0.29),
            np.clip(rng.normal(0, 0.4, 3), -1.3, 1.3),
            np.tile(rng.uniform(lo + args.margin, hi - args.margin), k),
        ]
        sol = least_squares(residual, x0, bounds=(lower, upper), diff_step=1e-6, max_nfev=400)
        if best is None or sol.cost < best.cost:
            best = sol
    assert best is not None
    for i, tilt in enumerate(tilts):
        pose(best.x, i)
        err = np.abs(d.site_xpos[tips] - targets[i]).max()
        gap = min(mujoco.mj_geomDistance(m, d, g, pen_geom, 0.02, fromto) for g in hand_geoms)
        q = best.x[6 + n * i : 6 + n * (i + 1)]
        edge = np.min(np.minimum(q - lo, hi - q))
        print(
            f"tilt {tilt:+.2f} rad: tip error {err:.1e} m, link gap {gap * 1e3:.1f} mm, "
            f"nearest joint limit {edge:.3f} rad, distal cosines {np.round(cosines(), 2)}, "
            f"tip-axis cosines {np.round(d.geom_xmat[tip_geoms_ordered, 8] * push, 2)}"
        )
    pose(best.x, 0)
    err = np.abs(d.site_xpos[tips] - targets[0]).max()
    gap = min(mujoco.mj_geomDistance(m, d, g, pen_geom, 0.02, fromto) for g in hand_geoms)
    w = (Rotation.from_rotvec(best.x[3:6]) * UPRIGHT).as_quat()
    inner = min(mujoco.mj_geomDistance(m, d, a, b, 0.02, fromto) for a, b in pairs)
    d.qpos[mount : mount + 3] += [0.0, 0.0, 1.0]  # the forearm off the floor (fixed later)
    mujoco.mj_forward(m, d)
    others = [
        (m.geom(a).name, m.geom(b).name, round(float(dist) * 1e3, 2))
        for (a, b), dist in zip(d.contact.geom, d.contact.dist, strict=True)
        if pen_geom not in (a, b)
    ]
    print(
        f"tip error {err:.2e} m, smallest link gap {gap * 1e3:.2f} mm, smallest finger-pair "
        f"gap {inner * 1e3:.2f} mm, other contacts {others}, cost {best.cost:.3e}"
    )
    print(f"{hand.prefix}_MOUNT = (")
    print(f"    ({best.x[0]:.9f}, {best.x[1]:.9f}, {best.x[2]:.9f}),")
    print(f"    ({w[3]:.9f}, {w[0]:.9f}, {w[1]:.9f}, {w[2]:.9f}),")
    print(")")
    # the keyframe exactly on the targets: the grasp's own inverse kinematics from there
    placed = (tuple(best.x[:3]), (w[3], w[0], w[1], w[2]))
    start = tuple(tuple(best.x[6 + 3 * f : 9 + 3 * f]) for f in range(len(fingers)))
    final = hand.spec(mount=placed, grasp=start).compile()
    physics = PenHandPhysics(final, mujoco.MjData(final), [f.name for f in fingers], sides=sides)
    physics.reset()
    err = place_grasp(
        physics,
        np.zeros(3),
        np.zeros(3),
        args.contact_x,
        PENETRATION,
        iterations=100,
        tolerance=1e-12,
    )
    print(f"keyframe by the grasp's inverse kinematics: tip error {err:.1e} m")
    contacts = physics.fingertip_contacts()
    print(
        f"keyframe tip depths {np.round(contacts.depth * 1e3, 3)} mm (asked "
        f"{PENETRATION * 1e3:.1f}), active {contacts.active}, link contacts "
        f"{physics.n_link_contacts()}"
    )
    polished = physics.hand_qpos()
    print(f"{hand.prefix}_GRASP = (")
    for f in range(len(fingers)):
        a = polished[3 * f : 3 * f + 3]
        print(f"    ({a[0]:.9f}, {a[1]:.9f}, {a[2]:.9f}),")
    print(")")
    for name, v, a, b in zip(names, best.x[6 : 6 + n], lo, hi, strict=True):
        print(f"  {name}: {v:+.3f} in [{a:+.3f}, {b:+.3f}]")


if __name__ == "__main__":
    main()

"""What a transfer carries from the human's grasp, and when a hand refuses a skill (Flow 2).

:func:`transfer_reference` carries the object's motion and the grasp margin. This module
decides, before anything runs, how the demonstration's grasp maps onto the target hand and
whether the hand can execute the skill at all (:func:`plan_transfer`, a
:class:`TransferPlan`).

**The mapping of contacts.** A glove session holds the pen in a two-pad pinch: the index
presses it from the top side, the thumb carries it from below. A robot hand holds it with 3-5
fingertips, each on one side of the pen (``HandSpec.sides``). Each target finger takes the
role of the demonstration's contacts on its side: on ias4f f1 and f4 (top) are the index,
f2 and f3 (below) the thumb; on the LEAP hand, whose thumb is on top, the thumb is the
index's stand-in. A finger inherits its side's

- **contact schedule**: it touches while a contact of its side touches. A glove skill's pads
  hold the pen throughout its motion; a scheduled *slide* (eq. 20) is something a transfer
  does not execute (every target finger holds; sliding is ``IAS-PenSlide-v0``), so a skill
  that slides a contact inside the executed window is refused;
- **margin per contact** (:func:`~ias_gym.grasp.grasp_margin.contact_margins`): the squeeze
  of the demonstrated kind at which that contact alone would reach its friction cone's
  boundary. The grasp margin is their minimum. The target reproduces the grasp margin (one
  scale of its internal forces, the null space of its W: eq. 7). The other contacts'
  margins then follow from the target's own internal-force LP. Setting them one by one would
  need forces outside that null space, which would move the object. They are reported, not
  imposed.

**When a hand refuses.** The motion is scaled into the hand's workspace (per axis below).
A hand refuses a skill when, scaled so, its motion could not be told from holding the pen
still by the person's own standard: a still pen would be within the skill class's
tolerance of the scaled reference, in rotation and in position
(:func:`~ias_gym.skills.tolerance.reference_distance`, the tolerances unscaled: the person's
repeatability), while it is not within the tolerance of the demonstration itself. Such an
execution would pass the scaled success test while showing nothing of the skill. A
demonstration that is itself within its person's spread of a still pen (some ``lift_hold``
sessions) is not refused: no hand can lose a motion that is not there.

Per axis, the plan reports the demonstration's largest excursion and the executed one: the
pen centre along x (the pen's initial heading), y (up) and z (lateral) [mm], and the axis'
tilt and turn [deg]. Translations share one scale and rotations another, the translation's
set by how far the hand carries the pen along each axis at the skill's tilt
(:func:`~ias_gym.skills.transfer.transfer_reference`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ias_gym.envs.skill_reference import SkillReference
from ias_gym.errors import SkillTransferError
from ias_gym.grasp.grasp_margin import contact_margins
from ias_gym.sim import hands
from ias_gym.skills.skill import Skill
from ias_gym.skills.tolerance import (
    Tolerance,
    reference_distance,
    skill_tolerance,
    still_reference,
)
from ias_gym.skills.transfer import (
    demonstration_friction,
    skill_motion,
    skill_start_index,
    transfer_reference,
)
from ias_gym.skills.workspace import HandWorkspace, hand_workspace

#: A glove session's contacts, in its skill model's order: the index on the pen's top side,
#: the thumb below it (:mod:`ias_gym.skills.glove_session`).
GLOVE_CONTACTS: tuple[tuple[str, float], ...] = (("index", 1.0), ("thumb", -1.0))
#: Side names of ``HandSpec.sides``.
SIDE_NAMES = {1.0: "top", -1.0: "bottom"}
#: An unbounded workspace: the demonstration's own motion, unscaled.
UNSCALED = HandWorkspace(reach=math.inf, tilt=math.inf)


@dataclass(frozen=True)
class FingerRole:
    """One target finger's share of the demonstrated grasp.

    Attributes:
        finger: the target finger's name (``HandSpec.fingers``).
        side: ``"top"`` or ``"bottom"``, the side of the pen it touches.
        contacts: the demonstration's contacts on that side, whose role it takes.
        touching: the share of the executed window in which one of them touches [-].
        margin: the median demonstrated margin of the weakest of them over that window [-]
            (``inf``: no squeeze needed there; NaN: never measured).
    """

    finger: str
    side: str
    contacts: tuple[str, ...]
    touching: float
    margin: float


@dataclass(frozen=True)
class TransferPlan:
    """The transfer of one skill to one hand, decided before it runs.

    Attributes:
        hand, skill_id, person, name: which hand and skill.
        roles: per target finger, its :class:`FingerRole`.
        demonstrated_mm, executed_mm: the pen centre's largest excursion per axis
            (``x``, ``y``, ``z``) in the demonstration and in the executed reference [mm].
        demonstrated_deg, executed_deg: the axis' largest ``tilt`` and ``turn`` [deg].
        scale, scale_rotation: the reference's translation and rotation scales [-].
        refused: why the hand refuses the skill (one line), or None.
        too_small: it refuses for its workspace (another hand may take the skill), not for
            the skill's contacts (no hand would).
        reference: the reference the hand executes (:func:`transfer_reference` over the
            planned window).
    """

    hand: str
    skill_id: int
    person: str
    name: str
    roles: tuple[FingerRole, ...]
    demonstrated_mm: dict[str, float]
    executed_mm: dict[str, float]
    demonstrated_deg: dict[str, float]
    executed_deg: dict[str, float]
    scale: float
    scale_rotation: float
    refused: str | None
    too_small: bool
    reference: SkillReference

    def to_json(self) -> dict[str, Any]:
        """The plan as a JSON-ready dict (units in the keys; a non-finite margin is None)."""

        def number(x: float) -> float | None:
            return round(x, 4) if math.isfinite(x) else None

        return {
            "refused": self.refused,
            "demonstrated_mm": self.demonstrated_mm,
            "executed_mm": self.executed_mm,
            "demonstrated_deg": self.demonstrated_deg,
            "executed_deg": self.executed_deg,
            "fingers": [
                {
                    "finger": r.finger,
                    "side": r.side,
                    "contacts": list(r.contacts),
                    "touching_share": round(r.touching, 4),
                    "margin_demonstrated": number(r.margin),
                }
                for r in self.roles
            ],
        }

    def refusal_row(self) -> dict[str, Any]:
        """A refusing hand's result: which skill, not a success, why, and the plan."""
        return {
            "hand": self.hand,
            "skill_id": self.skill_id,
            "person": self.person,
            "skill": self.name,
            "success": False,
            "scale": self.scale,
            "scale_rot": self.scale_rotation,
            **self.to_json(),
        }


def source_contacts(skill: Skill) -> tuple[tuple[str, float], ...]:
    """The demonstration's contacts as ``(name, side)``, in its skill model's order.

    A two-contact record is the glove's pinch (:data:`GLOVE_CONTACTS`); a record of a pen
    task carries its hand's fingers and sides (``env_kwargs["hand"]``, else the task's
    default hand).

    Raises:
        SkillTransferError: the record's number of contacts fits neither.
    """
    k = skill.model.touching.shape[1]
    if k == len(GLOVE_CONTACTS):
        return GLOVE_CONTACTS
    spec = hands.get_hand(str(skill.env_kwargs.get("hand", hands.DEFAULT_HAND)))
    if spec.n_fingers != k:
        raise SkillTransferError(
            f"skill {skill.id} ({skill.name}) has {k} contacts; neither a glove pinch nor the "
            f"{spec.n_fingers} fingers of hand {spec.name!r}: its contacts have no sides"
        )
    return tuple(zip(spec.fingers, spec.sides, strict=True))


def _still_passes(reference: SkillReference, tolerance: Tolerance) -> bool:
    """A still pen is within ``tolerance`` of ``reference`` in rotation and position."""
    rotation, position, _ = reference_distance(still_reference(reference), reference)
    return rotation <= tolerance.rotation and position <= tolerance.position


def plan_transfer(
    skill: Skill,
    hand: str,
    duration: float | None = None,
    tolerances: dict[str, Tolerance] | None = None,
) -> TransferPlan:
    """Map a skill's grasp onto a hand and decide whether the hand can execute it.

    Args:
        skill: the stored skill (e.g. a glove session).
        hand: the target hand's name.
        duration: the executed window after the skill's start [s] (default: all of it).
        tolerances: the success tolerances by skill class (default: the shipped ones).

    Returns:
        The :class:`TransferPlan`; ``refused`` says why when the hand refuses.

    Raises:
        SkillTransferError: the skill has no grasp to transfer.
        InputError: an unknown hand.
    """
    spec = hands.get_hand(hand)
    model = skill.model
    start = skill_start_index(skill)
    t_rel = model.time[start:] - model.time[start]
    window = slice(start, start + int(np.searchsorted(t_rel, (duration or math.inf) + 1e-9)))
    contacts = source_contacts(skill)
    refused: str | None = None

    sliding = np.flatnonzero(model.sliding[window].any(axis=0))
    if sliding.size:
        i = int(sliding[0])
        when = float(model.time[window][np.argmax(model.sliding[window][:, i])] - model.time[0])
        refused = (
            f"skill {skill.id} ({skill.name}) slides its {contacts[i][0]} contact from "
            f"t = {when:.2f} s; a transfer holds every finger (sliding is IAS-PenSlide-v0)"
        )

    per_contact = _contact_margins(skill, window)
    roles = []
    for finger, side in zip(spec.fingers, spec.sides, strict=True):
        mine = [i for i, (_, s) in enumerate(contacts) if s == side]
        if not mine and refused is None:
            refused = (
                f"hand {hand} has a finger on the pen's {SIDE_NAMES[side]} side; skill "
                f"{skill.id} ({skill.name}) has no contact there to map onto it"
            )
        touching = model.touching[window][:, mine].any(axis=1) if mine else np.zeros(1, bool)
        weakest = per_contact[:, mine].min(axis=1) if mine else np.array([math.nan])
        known = weakest[~np.isnan(weakest)]
        roles.append(
            FingerRole(
                finger=finger,
                side=SIDE_NAMES[side],
                contacts=tuple(contacts[i][0] for i in mine),
                touching=float(np.mean(touching)),
                margin=float(np.median(known)) if known.size else math.nan,
            )
        )

    reference = transfer_reference(skill, hand, duration=duration, tolerances=tolerances)
    full = transfer_reference(skill, workspace=UNSCALED, duration=duration, tolerances=tolerances)
    tolerance = skill_tolerance(skill.name, tolerances)
    shows_nothing = _still_passes(reference, tolerance) and not _still_passes(full, tolerance)
    too_small = refused is None and shows_nothing
    displacement, angles = skill_motion(skill)
    if too_small:
        ws = hand_workspace(hand)
        turn = reference.scale_rotation * float(np.max(np.hypot(angles[:, 0], angles[:, 1])))
        refused = (
            f"hand {hand} {ws.describe_motion()} and {ws.describe_reach(turn)} at this tilt: "
            f"{skill.name} skill "
            f"{skill.id} scaled into it "
            f"(translation x{reference.scale:.2f}, rotation x{reference.scale_rotation:.2f}) "
            f"is within its person's own repeatability of a still pen "
            f"({1000 * tolerance.position:.1f} mm, {math.degrees(tolerance.rotation):.1f} deg "
            "RMS)"
        )

    demo_mm = 1000.0 * np.max(np.abs(displacement), axis=0)
    demo_deg = np.degrees(np.max(np.abs(angles), axis=0))

    def axes(values: Any, names: tuple[str, ...]) -> dict[str, float]:
        return {n: round(float(v), 3) for n, v in zip(names, values, strict=True)}

    return TransferPlan(
        hand=hand,
        skill_id=-1 if skill.id is None else int(skill.id),
        person=skill.person_id or "",
        name=skill.name,
        roles=tuple(roles),
        demonstrated_mm=axes(demo_mm, ("x", "y", "z")),
        executed_mm=axes(reference.scale * demo_mm, ("x", "y", "z")),
        demonstrated_deg=axes(demo_deg, ("tilt", "turn")),
        executed_deg=axes(reference.scale_rotation * demo_deg, ("tilt", "turn")),
        scale=reference.scale,
        scale_rotation=reference.scale_rotation,
        refused=refused,
        too_small=too_small,
        reference=reference,
    )


def _contact_margins(skill: Skill, window: slice) -> np.ndarray:
    """``(W, k)`` each contact's demonstrated margin in ``window``, NaN where a contact is
    missing (as :func:`~ias_gym.skills.transfer.demonstrated_margin`)."""
    m = skill.model
    mu, mu_t = demonstration_friction(skill)
    touching, c_p, c_h = m.touching[window], m.c_p[window], m.c_h[window]
    per = c_p.shape[1] // touching.shape[1]
    out = np.full(touching.shape, math.nan)
    for t in np.flatnonzero(touching.all(axis=1)):
        out[t] = contact_margins(c_p[t], c_h[t], mu, mu_t, per)
    return out

"""The sensors every pen hand has, added in code to a hand that another project built.

:mod:`ias_gym.sim.pen_hand` reads, per finger ``fN``: the touch sensor ``fN_touch`` on the
tip site ``fN_tip``, and two contact sensors of the tip geom ``fN_tip_collision`` with the
pen: ``fN_pen_contact`` (the deepest contact's found, force, dist, pos, normal, tangent) and
``fN_pen_force`` (the net force of all of them), as ``scene_pen.xml`` declares them.
"""

from __future__ import annotations

import mujoco

#: The pip extra that installs the external hands' packages.
EXTRA = "hands"


def add_pen_sensors(scene: mujoco.MjSpec, fingers: list[str]) -> None:
    """The sensors every pen hand has, per finger (its ``fN_tip`` site and
    ``fN_tip_collision`` geom must exist): ``fN_touch`` on the tip site, then per finger the
    contact sensors ``fN_pen_contact`` and ``fN_pen_force`` (:mod:`ias_gym.sim.pen_hand`
    reads them in this order)."""
    for finger in fingers:
        scene.add_sensor(
            name=f"{finger}_touch",
            type=mujoco.mjtSensor.mjSENS_TOUCH,
            objtype=mujoco.mjtObj.mjOBJ_SITE,
            objname=f"{finger}_tip",
        )
    for finger in fingers:
        _contact_sensor(scene, f"{finger}_pen_contact", finger, detail=True)
    for finger in fingers:
        _contact_sensor(scene, f"{finger}_pen_force", finger, detail=False)


def _contact_sensor(scene: mujoco.MjSpec, name: str, finger: str, *, detail: bool) -> None:
    """A contact sensor of the finger's tip geom with the pen, as scene_pen.xml's: the
    deepest contact's found, force, dist, pos, normal, tangent (``detail``), or the net
    force of all of them."""
    fields = (
        ("FOUND", "FORCE", "DIST", "POS", "NORMAL", "TANGENT") if detail else ("FOUND", "FORCE")
    )
    data = sum(1 << int(getattr(mujoco.mjtConDataField, f"mjCONDATA_{f}")) for f in fields)
    reduce = 1 if detail else 3  # MJCF's reduce="mindist" / "netforce"
    scene.add_sensor(
        name=name,
        type=mujoco.mjtSensor.mjSENS_CONTACT,
        objtype=mujoco.mjtObj.mjOBJ_GEOM,
        objname=f"{finger}_tip_collision",
        reftype=mujoco.mjtObj.mjOBJ_GEOM,
        refname="pen",
        intprm=[data, reduce, 1],
    )

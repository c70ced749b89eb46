"""The gains of the grip-transform controller (:mod:`~.grip_transform_control`), one frozen
dataclass: the law's stiffnesses and damping, the internal-force problem's settings and the
switches of what the controller adds beyond the paper (docs/controller.md says why each is
what it is)."""

from __future__ import annotations

from dataclasses import dataclass, field

from ias_gym.grasp.internal_forces import Cone
from ias_gym.sim.scene_constants import pen_friction


@dataclass(frozen=True)
class ControllerGains:
    """Gains of the grip-transform controller (units in the comments)."""

    kp: float = 400.0  # object position stiffness Kp [1/s^2] (eq. 43)
    kv: float = 40.0  # object position damping Kv [1/s]
    # Integral of the object position error [1/s^3] (Routh: ki < Kp Kv): takes out a steady
    # offset Kp leaves, e.g. where the tips' lateral servo pulls a moved pen back; off for the
    # pen tasks, per hand for transferred skills (skills.transfer_run.TRANSFER_KI).
    ki: float = 0.0
    # The integral's share of a_d is bounded by this [m/s^2] (anti-windup: half of g, a pen
    # between 0.5 and 1.5 times its nominal weight).
    integral_limit: float = 4.9
    # Time constant [s] of the pen's mass estimated from the measured tip forces (their net
    # force against gravity, low-pass filtered, while every finger touches; quasi-static:
    # the skills' accelerations are about 1 % of g); 0: the law uses the nominal mass.
    mass_time_constant: float = 0.1
    kp_rot: float = 400.0  # object orientation stiffness [1/s^2]
    kv_rot: float = 40.0  # object orientation damping [1/s]
    delta: float = 50.0  # internal-force error rate delta of eq. (44) [1/s]
    kp_slide: float = 90.0  # sliding-tip stiffness along the pen [N/m] (docs/controller.md)
    kv_slide: float = 2.0  # sliding-tip damping [N s/m] (train/tune_slide_servo.py chose both)
    kp_lateral: float = 20.0  # tip stiffness across the pen, toward its top/bottom line [N/m]
    kv_lateral: float = 1.5  # tip damping across the pen [N s/m]
    friction_margin: float = 0.4  # sticking contacts use mu (1 - margin) [-]
    # friction coefficient the controller assumes [-]: the nominal pen's (pen.xml)
    mu: float = field(default_factory=pen_friction)
    cone: Cone = "polygon"  # friction cone of the internal-force problem: box or polygon
    jacobian_damping: float = 1e-6  # damping of J+ [m^2]
    finger_inertia: bool = True  # include the M J+ {...} terms of eq. (45)
    lead: float = 0.0  # evaluate the reference this far ahead [s]
    damping_feedforward: bool = True  # add the joints' damping along the reference motion
    coulomb_speed: float = 0.005  # [rad/s] their Coulomb friction's smoothed sign (0: none)
    # the holding torques J^T f + H first where the motors saturate (docs/controller.md)
    hold_first: bool = True
    # a skill's squeeze never below this share of each finger's force resolution (its
    # joints' dry friction; fitted by train/fit_gain.py, docs/controller.md)
    friction_floor: float = 0.5
    # A skill's squeeze is scaled to its margin with the friction coefficient the tips have
    # shown (friction_estimate.FrictionEstimate): the mean ratio of tangential to normal
    # force of a tip that slid over the pen faster than slip_speed [m/s] for slip_time [s];
    # the nominal mu until one has. inf: always mu. Fitted by train/fit_gain.py.
    slip_speed: float = 0.005
    slip_time: float = 0.03
    # ... or whose ratio comes back to its highest value so far (within plateau_tolerance
    # of it, relative) on steps adding up to plateau_time [s]: a tip pinned on its cone
    # that creeps too slowly for a slide. 0: no such reading; per hand for transferred
    # skills (skills.transfer_run.TRANSFER_PLATEAU, fitted by train/fit_gain.py).
    plateau_time: float = 0.0
    plateau_tolerance: float = 0.002
    # A skill's margin is held at least at this [-]: the robot's own safety margin, for
    # what its model of the grasp does not know (friction, contact places, lag); the
    # demonstrated margin where it is larger. 1.0: the demonstration's alone. Fitted by
    # train/fit_gain.py (docs/controller.md).
    margin_floor: float = 1.1
    # A fingertip off the pen closes on it again at this speed [m/s] relative to the pen's
    # measured motion at the tip: its joints' damping and dry friction paid along that
    # motion (grip_transform_terms.approach_torques); 0: an off finger gets only its force.
    # Fitted by train/fit_gain.py (docs/controller.md).
    approach_speed: float = 0.01

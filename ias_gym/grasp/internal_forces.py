"""Internal grasp forces by optimisation, eqs. (19)-(24).

Given the wrench matrix ``W`` of eq. (3) (the modern *grasp matrix*) of ``m`` hard-finger
contacts and the external wrench ``w_ext`` on the object, find the wrench intensities ``c``
(per contact ``[normal, t1, t2]``, the column order of
:func:`ias_gym.grasp.wrench_matrix.wrench_matrix`; a compressive contact has ``c_n > 0``) that

- hold the object: ``W c = -w_ext`` (the fingers cancel the external wrench, e.g. the weight
  ``w_ext = [0, -m g, 0, 0, 0, 0]`` of eq. 18; docs/NOTES.md "Sign of gravity");
- keep every contact closed: ``c_n >= f0`` (eq. 19);
- keep sticking contacts inside their friction cone: the paper's box
  ``|c_t1| <= mu c_n, |c_t2| <= mu c_n`` (eqs. 21-24), the exact Coulomb cone
  ``||(c_t1, c_t2)|| <= mu c_n``, or an eight-sided pyramid inscribed in it (``"polygon"``:
  linear like the box, but never outside the true cone; the box's corners are ``sqrt(2)``
  outside it, docs/controller.md);
- put a sliding contact's tangential force on the cone in its sliding direction,
  ``(c_t1, c_t2) = mu c_n s`` (kinetic Coulomb friction, docs/NOTES.md "Sliding contact"), where
  ``s`` is the unit direction of the finger's velocity relative to the object in (t1, t2)
  coordinates; the paper's eq. (20), ``c_t1 + mu c_n < 0``, is the case ``s = (-1, 0)``;

and minimise the (weighted) sum of the normal forces.

Our choices, beyond the paper: the equality for sliding contacts (the paper-literal
inequality is kept as ``sliding="paper"``, generalised to ``s . c_t >= mu c_n``; it lets the
optimum pick tangential forces a contact cannot deliver); the exact cone; and a friction safety
``margin``: sticking contacts use ``mu (1 - margin)`` because the minimum-force optimum sits
exactly on the cone boundary. Sliding contacts always use the true ``mu``.

Solvers (times per solve of the 4-finger pen, ``bench/bench_internal_forces.py``):

- :func:`solve_lp`: ``scipy.optimize.linprog(method="highs")``, the paper-faithful
  reference (box cones), about 1.6 ms;
- :func:`solve_socp`: Clarabel, exact cones, about 0.4 ms;
- :class:`InternalForceSolver`: the control-loop path, a persistent, warm-started DAQP
  workspace solving the box-cone problem as a slightly regularised QP, about 25 us;
- :func:`solve_internal_forces`: picks :func:`solve_lp` or :func:`solve_socp` from
  ``settings.cone``.

Units are SI: forces [N], moments [N m].

Where the code lives (this module re-exports the public names):
:mod:`~ias_gym.grasp.internal_forces_problem` the settings, result, checks and constraint
rows; :mod:`~ias_gym.grasp.internal_forces_reference` the LP and SOCP;
:mod:`~ias_gym.grasp.internal_forces_daqp` the control-loop solver.
"""

from ias_gym.grasp.internal_forces_daqp import InternalForceSolver
from ias_gym.grasp.internal_forces_problem import (
    POLYGON_DIRECTIONS,
    POLYGON_SCALE,
    Cone,
    FloatArray,
    InfeasibleGraspError,
    InternalForceResult,
    InternalForceSettings,
    Sliding,
    SlidingModel,
    friction_cone_residual,
    sliding_direction,
)
from ias_gym.grasp.internal_forces_reference import solve_internal_forces, solve_lp, solve_socp

# The names other modules import from here (the code lives in internal_forces_*.py).
__all__ = [
    "POLYGON_DIRECTIONS",
    "POLYGON_SCALE",
    "Cone",
    "FloatArray",
    "InfeasibleGraspError",
    "InternalForceResult",
    "InternalForceSettings",
    "InternalForceSolver",
    "Sliding",
    "SlidingModel",
    "friction_cone_residual",
    "sliding_direction",
    "solve_internal_forces",
    "solve_lp",
    "solve_socp",
]

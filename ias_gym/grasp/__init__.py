"""The paper's grasp model, pure math (numpy, scipy; no MuJoCo, no I/O).

- :mod:`~ias_gym.grasp.wrench_matrix`: contact wrench bases and the wrench matrix W (eq. 3);
- :mod:`~ias_gym.grasp.grip_transform`: W+, N and the grip transform G (eqs. 4-15);
- :mod:`~ias_gym.grasp.internal_forces`: internal forces by optimisation (eqs. 19-24);
- :mod:`~ias_gym.grasp.pen_skill`: the sliding pen of sections 3.2 and 4.2 (eqs. 16-18).
"""

from ias_gym.grasp.grip_transform import (
    GraspRankError,
    GripTransform,
    null_space_basis,
    pseudo_inverse,
)
from ias_gym.grasp.internal_forces import (
    InfeasibleGraspError,
    InternalForceResult,
    InternalForceSettings,
    InternalForceSolver,
    solve_internal_forces,
    solve_lp,
    solve_socp,
)
from ias_gym.grasp.pen_skill import PenSkillParams, pen_wrench_matrix, wrench_intensities
from ias_gym.grasp.wrench_matrix import ContactModel, contact_wrench_basis, wrench_matrix

__all__ = [
    "ContactModel",
    "GraspRankError",
    "GripTransform",
    "InfeasibleGraspError",
    "InternalForceResult",
    "InternalForceSettings",
    "InternalForceSolver",
    "PenSkillParams",
    "contact_wrench_basis",
    "null_space_basis",
    "pen_wrench_matrix",
    "pseudo_inverse",
    "solve_internal_forces",
    "solve_lp",
    "solve_socp",
    "wrench_intensities",
    "wrench_matrix",
]

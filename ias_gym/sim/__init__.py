"""ias_gym.sim: the physics side (MuJoCo models answering the paper's named questions)."""

from ias_gym.sim.hands import HANDS, HandSpec, get_hand, hand_names
from ias_gym.sim.pen_hand import (
    FINGER_JOINTS,
    FINGERS,
    GRASP_KEYFRAME,
    R_PAPER_TO_MJ,
    FingertipContacts,
    NameNotFoundError,
    PenHandPhysics,
    load_pen_hand_model,
    matrix_to_rpy,
    mj_to_paper,
    paper_to_mj,
    rpy_to_matrix,
    wrench_mj_to_paper,
    wrench_paper_to_mj,
)

__all__ = [
    "FINGERS",
    "FINGER_JOINTS",
    "GRASP_KEYFRAME",
    "HANDS",
    "R_PAPER_TO_MJ",
    "FingertipContacts",
    "HandSpec",
    "NameNotFoundError",
    "PenHandPhysics",
    "get_hand",
    "hand_names",
    "load_pen_hand_model",
    "matrix_to_rpy",
    "mj_to_paper",
    "paper_to_mj",
    "rpy_to_matrix",
    "wrench_mj_to_paper",
    "wrench_paper_to_mj",
]

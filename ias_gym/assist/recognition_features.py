"""The recognisers' features of a glove session frame (paper Flow 3).

What both recognisers (:mod:`ias_gym.assist.recognition`) see of a frame: the wrist's
calibrated angles and the pen's pose, each over its scale (:data:`FEATURE_NAMES`,
:data:`FEATURE_SCALE`), relative to the frame at :data:`FEATURE_T0`, the end of the shared
lift, and zero before it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ias_gym.assist.stream import SessionFrame
from ias_gym.errors import InputError
from ias_gym.glove.hand import joint_index
from ias_gym.glove.skills import SKILL_TIMINGS

FloatArray = NDArray[np.float64]

#: Recogniser features: the wrist's calibrated angles (the operator's intent) and the pen's
#: pose (the object-level skill); its roll about its own axis is left out (the pinched pen
#: rolls between the pads by a person-dependent amount whatever the skill).
FEATURE_NAMES: tuple[str, ...] = (
    "theta_wrist_flexion",
    "theta_wrist_deviation",
    "theta_wrist_pronation",
    "pen_pitch",
    "pen_yaw",
    "pen_x",
    "pen_y",
    "pen_z",
)
#: Each feature is divided by its scale [rad or m]: 0.05 rad and 5 mm weigh alike.
FEATURE_SCALE = np.array([0.05, 0.05, 0.05, 0.05, 0.05, 0.005, 0.005, 0.005])
_THETA_IDX = np.array(
    [joint_index(j) for j in ("wrist_flexion", "wrist_deviation", "wrist_pronation")]
)
#: Episode time [s] from which skills may differ: the end of the scripted lift of the glove
#: protocol, the same for everyone (before it every session is the same reach-pinch-lift).
FEATURE_T0 = SKILL_TIMINGS.lift - SKILL_TIMINGS.reach


def features(frame: SessionFrame) -> FloatArray:
    """The frame's raw feature vector (:data:`FEATURE_NAMES` / FEATURE_SCALE).

    Args:
        frame: one step of a session.

    Returns:
        ``(8,)`` dimensionless features.
    """
    raw = np.concatenate([frame.theta[_THETA_IDX], frame.pen_rpy[1:3], frame.pen_position])
    return raw.astype(np.float64) / FEATURE_SCALE


def feature_matrix(frames: Sequence[SessionFrame]) -> FloatArray:
    """``(T, 8)`` recogniser features of a session: :func:`features` relative to the frame at
    :data:`FEATURE_T0`, zero before it.

    Where a person's hand holds the pen (its lateral offset, a few mm) is theirs, not the
    skill's: the recognisers see how the features move from the end of the lift on, when
    the skills may begin, and nothing of the shared pinch-lift before.

    Raises:
        InputError: no frames.
    """
    if not frames:
        raise InputError("a session needs at least one frame")
    raw = np.stack([features(f) for f in frames])
    times = np.array([f.time_s for f in frames])
    return _relative(raw, times)


def _relative(raw: FloatArray, times: FloatArray) -> FloatArray:
    after = times >= FEATURE_T0 - 1e-9
    if not after.any():
        return np.zeros_like(raw)
    ref = raw[int(np.argmax(after))]
    return np.where(after[:, None], raw - ref, 0.0)

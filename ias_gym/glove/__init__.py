"""The sensor glove: sensor model, per-person calibration, profiles, devices (paper 2.3-2.4).

- :mod:`~ias_gym.glove.hand`: the 10 joints Θ and 10 readings Ψ (names, order, ranges
  [rad]), a person's parameters (:class:`PersonParams`), the planar index/thumb kinematics.
- :mod:`~ias_gym.glove.sensor_model`: Ψ = g_person(Θ) + noise (eq. (1) inverted; the index
  linkage of Fig. 4, the pinch cross-coupling of Fig. 7) and calibration sessions.
- :mod:`~ias_gym.glove.calibration`: :class:`Calibration`, Θ = f(Ψ) in numpy (ANN and linear
  group models), the linear least-squares baseline, held-out metrics.
- :mod:`~ias_gym.glove.training`: torch training of the ANNs (the ``[glove]`` extra); its
  names are imported from here only on first use, so importing this package (and loading a
  profile, and predicting) never imports torch.
- :mod:`~ias_gym.glove.profile`: a person's profile as safe JSON, atomic writes, checked loads.
- :mod:`~ias_gym.glove.device`: the :class:`GloveDevice` interface, :class:`SimulatedGlove`
  and the scripted operator :class:`ReachPinchLift`.
- :mod:`~ias_gym.glove.operator`: the scripted pen pinch of the glove world
  (:func:`~ias_gym.glove.operator.pen_operator`, :class:`~ias_gym.glove.operator.FromPreShape`).
- :mod:`~ias_gym.glove.skills`: the object-level skills a person performs with the pinched
  pen after the pinch-lift (:data:`~ias_gym.glove.skills.SKILLS`), each person's style.
- :mod:`~ias_gym.glove.profile_cache`: the simulated persons' calibrations (any person id:
  trained once, cached as profiles).
- :mod:`~ias_gym.glove.impairments`: impaired operators (tremor, weak grip, lag, biased
  calibration, another hand size, a stop), named by the specs of
  :mod:`~ias_gym.glove.impairment_spec` (``NAME[:KEY=VALUE,...]``).
- :mod:`~ias_gym.glove.ids`: :func:`check_id`, the one rule for person and glove ids
  (they name files).

``ias-gym calibrate`` lives in :mod:`ias_gym.cli.glove_commands` (this package never imports the
command line).
"""

from __future__ import annotations

import importlib
from typing import Any

from ias_gym.glove.calibration import (
    ANN_GROUPS,
    LINEAR_GROUPS,
    PAPER_GROUPS,
    PAPER_LINEAR_GROUPS,
    Calibration,
    CalibrationMetrics,
    GroupModel,
    GroupSpec,
    evaluate,
    fit_linear,
)
from ias_gym.glove.device import (
    ACTUATED_JOINTS,
    GloveDevice,
    GloveReading,
    Operator,
    ReachPinchLift,
    ReachPinchLiftTimings,
    SimulatedGlove,
)
from ias_gym.glove.hand import (
    JOINT_NAMES,
    JOINT_RANGES,
    N_JOINTS,
    N_SENSORS,
    SENSOR_NAMES,
    PersonParams,
    fingertip_gap,
    hand_points,
)
from ias_gym.glove.ids import check_id
from ias_gym.glove.profile import Profile, ProfileError, load_profile, save_profile
from ias_gym.glove.sensor_model import (
    NOISE_STD,
    CalibrationSession,
    record_session,
    sensor_readings,
)

_LAZY = {
    "train_calibration": "ias_gym.glove.training",
    "calibrate_person": "ias_gym.glove.training",
    "CalibrationRun": "ias_gym.glove.training",
    "TrainingReport": "ias_gym.glove.training",
}


def __getattr__(name: str) -> Any:
    # Training needs torch: import it on first use only (PEP 562).
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "ACTUATED_JOINTS",
    "ANN_GROUPS",
    "JOINT_NAMES",
    "JOINT_RANGES",
    "LINEAR_GROUPS",
    "NOISE_STD",
    "N_JOINTS",
    "N_SENSORS",
    "PAPER_GROUPS",
    "PAPER_LINEAR_GROUPS",
    "SENSOR_NAMES",
    "Calibration",
    "CalibrationMetrics",
    "CalibrationRun",
    "CalibrationSession",
    "GloveDevice",
    "GloveReading",
    "GroupModel",
    "GroupSpec",
    "Operator",
    "PersonParams",
    "Profile",
    "ProfileError",
    "ReachPinchLift",
    "ReachPinchLiftTimings",
    "SimulatedGlove",
    "TrainingReport",
    "calibrate_person",
    "check_id",
    "evaluate",
    "fingertip_gap",
    "fit_linear",
    "hand_points",
    "load_profile",
    "record_session",
    "save_profile",
    "sensor_readings",
    "train_calibration",
]

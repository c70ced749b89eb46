"""Per-person glove calibration Θ = f(Ψ) (paper eq. (1), section 2.4): numpy inference.

A :class:`Calibration` is one small model per finger group (:class:`GroupModel`), each mapping
some sensor readings Ψ [rad] to some joint angles Θ [rad]; together the groups give every
joint exactly once. A group is either

- ``"ann"``: the paper's three-layer network, ``θ = y_mean + y_scale (W2 tanh(W1 x + b1) + b2)``
  with ``x = (ψ - x_mean) / x_scale`` (trained with torch by :mod:`ias_gym.glove.training`;
  inference here is numpy only, so a profile can be used without torch), or
- ``"linear"``: least squares with bias, ``θ = y_mean + y_scale (W x + b)``
  (:func:`fit_linear`, numpy).

The group layouts (:data:`ANN_GROUPS`, :data:`PAPER_GROUPS`, :data:`LINEAR_GROUPS`, our choice):

- wrist (3 -> 3) and other fingers (2 -> 2): linear. Their sensors are potentiometers and bend
  sensors whose readings are affine in the joint angles (mounting rotation, cross-talk,
  gain, offset; :mod:`ias_gym.glove.sensor_model`), so least squares inverts them exactly up
  to noise; a network would only add variance and training time.
- index finger (θ1, θ2, θ3): an ANN on ψ1, ψ2 *and* the thumb readings (web, flexion,
  rotation), 5 -> 24 -> 3. With ψ1, ψ2 alone the index is not recoverable in a pinch: two
  readings, three joints, and the DIP no longer follows the PIP; the contact with the
  thumb pins the fingertip, and the thumb readings say where. The paper's own network,
  ψ1, ψ2 -> 10 hidden -> θ1..θ3 (:data:`PAPER_GROUPS`), is kept and reported beside it.
- thumb (CMC, flexion): an ANN on the same five readings, 5 -> 12 -> 2: the pinch force
  pushes the thumb's bend sensor, and only the web/linkage readings tell how hard.

:meth:`Calibration.predict` folds the normalisation into the weights once, so a reading costs
three small matrix-vector products and a tanh. :func:`evaluate` gives the held-out errors:
joint-angle RMS [deg] over all joints, in free and in pinch poses, and the fingertip gap
error [mm] of the planar thumb-index kinematics (:func:`~ias_gym.glove.hand.tip_vector`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ias_gym.glove.hand import (
    JOINT_NAMES,
    N_JOINTS,
    N_SENSORS,
    PersonParams,
    joint_index,
    sensor_index,
    tip_vector,
)
from ias_gym.glove.sensor_model import CalibrationSession

ModelKind = Literal["ann", "linear"]
MODEL_KINDS: tuple[str, ...] = ("ann", "linear")
#: L-BFGS iterations per network in training (:mod:`ias_gym.glove.training`): the held-out
#: error has flattened by then for these sizes (600: +0.15 deg, 3000: -0.05 deg, 5 persons).
DEFAULT_MAX_ITER = 1500
#: Readings in a calibration session, and the share held out for the errors.
DEFAULT_READINGS = 2000
HELD_OUT_FRACTION = 0.2


@dataclass(frozen=True)
class GroupSpec:
    """What one group model maps, and how (before training).

    Attributes:
        name: group name (``"wrist"``, ``"index"``, ...).
        inputs: sensor names (:data:`~ias_gym.glove.hand.SENSOR_NAMES`).
        outputs: joint names (:data:`~ias_gym.glove.hand.JOINT_NAMES`).
        kind: ``"ann"`` or ``"linear"``.
        hidden: hidden nodes of an ANN (ignored for linear).
    """

    name: str
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    kind: ModelKind
    hidden: int = 10

    def __post_init__(self) -> None:
        for s in self.inputs:
            sensor_index(s)
        for j in self.outputs:
            joint_index(j)
        if self.kind not in MODEL_KINDS:
            raise ValueError(f"kind must be one of {MODEL_KINDS}, got {self.kind!r}")
        if self.kind == "ann" and self.hidden < 1:
            raise ValueError(f"an ANN needs hidden >= 1, got {self.hidden}")

    def as_kind(self, kind: ModelKind) -> GroupSpec:
        """The same group with another model kind."""
        return GroupSpec(self.name, self.inputs, self.outputs, kind, self.hidden)


_PINCH_INPUTS = ("index_psi1", "index_psi2", "thumb_web", "thumb_flexion", "thumb_rotation")
_WRIST = GroupSpec(
    "wrist",
    ("wrist_flexion", "wrist_deviation", "wrist_pronation"),
    ("wrist_flexion", "wrist_deviation", "wrist_pronation"),
    "linear",
)
_FINGERS = GroupSpec(
    "fingers", ("fingers_mcp", "fingers_pip"), ("fingers_mcp", "fingers_pip"), "linear"
)
_INDEX = GroupSpec("index", _PINCH_INPUTS, ("index_mcp", "index_pip", "index_dip"), "ann", 24)
_THUMB = GroupSpec("thumb", _PINCH_INPUTS, ("thumb_cmc", "thumb_flexion"), "ann", 12)
_INDEX_PAPER = GroupSpec(
    "index", ("index_psi1", "index_psi2"), ("index_mcp", "index_pip", "index_dip"), "ann", 10
)

#: The calibration we ship: ANNs for index and thumb, linear for wrist and other fingers.
ANN_GROUPS: tuple[GroupSpec, ...] = (_WRIST, _INDEX, _THUMB, _FINGERS)
#: As ANN_GROUPS, but the index network is the paper's 2-10-3 on ψ1, ψ2 only.
PAPER_GROUPS: tuple[GroupSpec, ...] = (_WRIST, _INDEX_PAPER, _THUMB, _FINGERS)
#: The linear baseline: every group of ANN_GROUPS as least squares with bias.
LINEAR_GROUPS: tuple[GroupSpec, ...] = tuple(g.as_kind("linear") for g in ANN_GROUPS)
#: The paper's "linear combination of ψ1, ψ2" for the index finger (4.1, Fig. 7(a)).
PAPER_LINEAR_GROUPS: tuple[GroupSpec, ...] = tuple(g.as_kind("linear") for g in PAPER_GROUPS)


def _as_2d(a: ArrayLike, name: str) -> NDArray[np.float64]:
    out = np.asarray(a, dtype=np.float64)
    if out.ndim != 2:
        raise ValueError(f"{name} must be 2-D, got shape {out.shape}")
    return out


@dataclass(frozen=True, eq=False)
class GroupModel:
    """One trained group model: normalisation constants and layer weights.

    Attributes:
        name: group name.
        kind: ``"ann"`` or ``"linear"``.
        inputs: sensor names it reads.
        outputs: joint names it gives.
        x_mean, x_scale: input normalisation [rad], ``(n_in,)``.
        y_mean, y_scale: output normalisation [rad], ``(n_out,)``.
        layers: ``((W, b), ...)`` in normalised units: ANN ``W1 (hidden, n_in), b1,
            W2 (n_out, hidden), b2``; linear one layer ``W (n_out, n_in), b``.
    """

    name: str
    kind: ModelKind
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    x_mean: NDArray[np.float64]
    x_scale: NDArray[np.float64]
    y_mean: NDArray[np.float64]
    y_scale: NDArray[np.float64]
    layers: tuple[tuple[NDArray[np.float64], NDArray[np.float64]], ...]

    def __post_init__(self) -> None:
        GroupSpec(self.name, self.inputs, self.outputs, self.kind)  # names and kind
        n_in, n_out = len(self.inputs), len(self.outputs)
        for name, n in (("x_mean", n_in), ("x_scale", n_in), ("y_mean", n_out), ("y_scale", n_out)):
            v = getattr(self, name)
            if np.shape(v) != (n,):
                raise ValueError(
                    f"group {self.name!r}: {name} must have shape ({n},), got {np.shape(v)}"
                )
        if np.any(np.asarray(self.x_scale) <= 0) or np.any(np.asarray(self.y_scale) <= 0):
            raise ValueError(f"group {self.name!r}: scales must be positive")
        expected = 2 if self.kind == "ann" else 1
        if len(self.layers) != expected:
            raise ValueError(
                f"group {self.name!r}: a {self.kind} model has {expected} layer(s), "
                f"got {len(self.layers)}"
            )
        width = n_in
        for k, (w, b) in enumerate(self.layers):
            rows = n_out if k == len(self.layers) - 1 else np.shape(w)[0]
            if np.ndim(w) != 2 or np.shape(w) != (rows, width) or np.shape(b) != (rows,):
                raise ValueError(
                    f"group {self.name!r}: layer {k} has W {np.shape(w)} and b {np.shape(b)}, "
                    f"expected W ({rows}, {width}) and b ({rows},)"
                )
            width = rows
        arrays = [self.x_mean, self.x_scale, self.y_mean, self.y_scale]
        arrays += [a for layer in self.layers for a in layer]
        if not all(np.all(np.isfinite(a)) for a in arrays):
            raise ValueError(f"group {self.name!r}: parameters must be finite")

    @property
    def hidden(self) -> int:
        """Hidden nodes (0 for a linear model)."""
        return int(self.layers[0][0].shape[0]) if self.kind == "ann" else 0

    @property
    def architecture(self) -> str:
        """``"5-24-3"`` for an ANN, ``"linear 2-2"`` for a linear model."""
        n_in, n_out = len(self.inputs), len(self.outputs)
        if self.kind == "ann":
            return f"{n_in}-{self.hidden}-{n_out}"
        return f"linear {n_in}-{n_out}"

    def predict(self, psi: ArrayLike) -> NDArray[np.float64]:
        """This group's joint angles [rad] from full readings Ψ ``(..., 10)`` [rad]."""
        p = np.asarray(psi, dtype=np.float64)
        x = (p[..., [sensor_index(s) for s in self.inputs]] - self.x_mean) / self.x_scale
        if self.kind == "ann":
            (w1, b1), (w2, b2) = self.layers
            y = np.tanh(x @ w1.T + b1) @ w2.T + b2
        else:
            ((w, b),) = self.layers
            y = x @ w.T + b
        return np.asarray(self.y_mean + self.y_scale * y)


@dataclass(frozen=True, eq=False)
class Calibration:
    """Θ = f(Ψ) for one person (eq. (1)): group models covering every joint once.

    Build one with :func:`fit_linear` or :func:`ias_gym.glove.training.train_calibration`, or
    load it from a profile (:func:`ias_gym.glove.profile.load_profile`).
    """

    groups: tuple[GroupModel, ...]
    _folded: dict[str, NDArray[np.float64]] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        seen = [j for g in self.groups for j in g.outputs]
        if sorted(seen) != sorted(JOINT_NAMES):
            missing = sorted(set(JOINT_NAMES) - set(seen))
            twice = sorted({j for j in seen if seen.count(j) > 1})
            raise ValueError(
                f"the groups must give every joint exactly once; missing {missing}, "
                f"given twice {twice}"
            )
        object.__setattr__(self, "_folded", self._fold())

    @property
    def kind(self) -> str:
        """``"ann"`` if any group is a network, else ``"linear"``."""
        return "ann" if any(g.kind == "ann" for g in self.groups) else "linear"

    def describe(self) -> str:
        """One line: the groups and their architectures."""
        return ", ".join(f"{g.name} {g.architecture}" for g in self.groups)

    def group(self, name: str) -> GroupModel:
        """The group model called ``name``.

        Raises:
            KeyError: listing the group names that exist.
        """
        for g in self.groups:
            if g.name == name:
                return g
        raise KeyError(f"no group {name!r}; groups: {[g.name for g in self.groups]}")

    def _fold(self) -> dict[str, NDArray[np.float64]]:
        # θ = c + A ψ + W2 tanh(W1 ψ + b1) in raw units [rad]: the normalisation of every
        # group folded into its weights, so predict() is three matrix products and a tanh.
        a = np.zeros((N_JOINTS, N_SENSORS))
        c = np.zeros(N_JOINTS)
        hidden = sum(g.hidden for g in self.groups)
        w1 = np.zeros((hidden, N_SENSORS))
        b1 = np.zeros(hidden)
        w2 = np.zeros((N_JOINTS, hidden))
        h0 = 0
        for g in self.groups:
            cols = [sensor_index(s) for s in g.inputs]
            rows = [joint_index(j) for j in g.outputs]
            inv = 1.0 / g.x_scale
            shift = g.x_mean * inv
            if g.kind == "ann":
                (gw1, gb1), (gw2, gb2) = g.layers
                h1 = h0 + g.hidden
                w1[h0:h1, cols] = gw1 * inv
                b1[h0:h1] = gb1 - gw1 @ shift
                w2[np.ix_(rows, range(h0, h1))] = g.y_scale[:, None] * gw2
                c[rows] = g.y_mean + g.y_scale * gb2
                h0 = h1
            else:
                ((gw, gb),) = g.layers
                a[np.ix_(rows, cols)] = g.y_scale[:, None] * gw * inv
                c[rows] = g.y_mean + g.y_scale * (gb - gw @ shift)
        return {"a_t": a.T.copy(), "c": c, "w1_t": w1.T.copy(), "b1": b1, "w2_t": w2.T.copy()}

    def predict(self, psi: ArrayLike) -> NDArray[np.float64]:
        """Joint angles Θ [rad] from sensor readings Ψ [rad] (eq. (1)).

        Args:
            psi: ``(10,)`` or ``(N, 10)`` readings in the order of
                :data:`~ias_gym.glove.hand.SENSOR_NAMES`.

        Returns:
            ``(10,)`` or ``(N, 10)`` joint angles in the order of
            :data:`~ias_gym.glove.hand.JOINT_NAMES`.

        Raises:
            ValueError: on a wrong shape or a non-finite reading.
        """
        p = np.asarray(psi, dtype=np.float64)
        if p.shape[-1:] != (N_SENSORS,) or p.ndim > 2:
            raise ValueError(f"psi must have shape (10,) or (N, 10), got {p.shape}")
        if not np.isfinite(p).all():
            raise ValueError("psi contains NaN or inf readings")
        f = self._folded
        theta = f["c"] + p @ f["a_t"]
        if f["b1"].size:  # any ANN group
            theta += np.tanh(p @ f["w1_t"] + f["b1"]) @ f["w2_t"]
        return np.asarray(theta)

    def predict_groupwise(self, psi: ArrayLike) -> NDArray[np.float64]:
        """As :meth:`predict`, group by group without folding (reference for tests)."""
        p = np.asarray(psi, dtype=np.float64)
        out = np.empty((*p.shape[:-1], N_JOINTS))
        for g in self.groups:
            out[..., [joint_index(j) for j in g.outputs]] = g.predict(p)
        return out


def normalisation(
    x: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Column means and standard deviations (a constant column gets scale 1)."""
    mean = x.mean(axis=0)
    scale = x.std(axis=0)
    return mean, np.where(scale > 1e-12, scale, 1.0)


def group_data(
    spec: GroupSpec, session: CalibrationSession
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The (inputs Ψ_g, targets Θ_g) of one group in a session [rad]."""
    x = session.psi[:, [sensor_index(s) for s in spec.inputs]]
    y = session.theta[:, [joint_index(j) for j in spec.outputs]]
    return x, y


def fit_linear_group(spec: GroupSpec, session: CalibrationSession) -> GroupModel:
    """Least squares with bias for one group (any ``spec.kind``; the result is linear)."""
    x, y = group_data(spec, session)
    xm, xs = normalisation(x)
    ym, ys = normalisation(y)
    xn = np.column_stack([(x - xm) / xs, np.ones(len(x))])
    coef, *_ = np.linalg.lstsq(xn, (y - ym) / ys, rcond=None)
    w = np.asarray(coef[:-1].T, dtype=np.float64).copy()
    b = np.asarray(coef[-1], dtype=np.float64).copy()
    return GroupModel(spec.name, "linear", spec.inputs, spec.outputs, xm, xs, ym, ys, ((w, b),))


def fit_linear(
    session: CalibrationSession, groups: Sequence[GroupSpec] = LINEAR_GROUPS
) -> Calibration:
    """The linear baseline: least squares with bias per group (numpy, no torch)."""
    return Calibration(tuple(fit_linear_group(g, session) for g in groups))


@dataclass(frozen=True)
class CalibrationMetrics:
    """Errors of a calibration on a (held-out) session.

    Attributes:
        n, n_pinch: readings, of which pinch poses.
        rms_deg: joint-angle RMS over all joints and readings [deg].
        free_rms_deg, pinch_rms_deg: the same over free / pinch poses only [deg].
        pinch_gap_mm: RMS over pinch poses of the error of the thumb-tip-minus-index-tip
            vector of the planar kinematics (true gap vs predicted gap) [mm].
        joint_rms_deg: per joint (order of JOINT_NAMES), all readings [deg].
        joint_pinch_rms_deg: per joint, pinch poses [deg].
    """

    n: int
    n_pinch: int
    rms_deg: float
    free_rms_deg: float
    pinch_rms_deg: float
    pinch_gap_mm: float
    joint_rms_deg: tuple[float, ...]
    joint_pinch_rms_deg: tuple[float, ...]

    def to_dict(self) -> dict[str, Any]:
        """JSON-able dict; per-joint values keyed by joint name."""
        return {
            "n": self.n,
            "n_pinch": self.n_pinch,
            "rms_deg": self.rms_deg,
            "free_rms_deg": self.free_rms_deg,
            "pinch_rms_deg": self.pinch_rms_deg,
            "pinch_gap_mm": self.pinch_gap_mm,
            "joint_rms_deg": dict(zip(JOINT_NAMES, self.joint_rms_deg, strict=True)),
            "joint_pinch_rms_deg": dict(zip(JOINT_NAMES, self.joint_pinch_rms_deg, strict=True)),
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> CalibrationMetrics:
        """Inverse of :meth:`to_dict`."""
        return cls(
            n=int(d["n"]),
            n_pinch=int(d["n_pinch"]),
            rms_deg=float(d["rms_deg"]),
            free_rms_deg=float(d["free_rms_deg"]),
            pinch_rms_deg=float(d["pinch_rms_deg"]),
            pinch_gap_mm=float(d["pinch_gap_mm"]),
            joint_rms_deg=tuple(float(d["joint_rms_deg"][j]) for j in JOINT_NAMES),
            joint_pinch_rms_deg=tuple(float(d["joint_pinch_rms_deg"][j]) for j in JOINT_NAMES),
        )


def _rms(a: NDArray[np.float64], axis: int | None = None) -> NDArray[np.float64]:
    if a.size == 0:
        return np.asarray(np.full(a.shape[1] if axis == 0 else (), np.nan))
    return np.asarray(np.sqrt(np.mean(a**2, axis=axis)))


def gap_errors_mm(
    theta_true: ArrayLike, theta_pred: ArrayLike, person: PersonParams
) -> NDArray[np.float64]:
    """Per pose, |(thumb tip - index tip)(Θ̂) - (thumb tip - index tip)(Θ)| [mm]."""
    d = tip_vector(theta_pred, person) - tip_vector(theta_true, person)
    return np.asarray(1e3 * np.linalg.norm(d, axis=-1))


def evaluate(calibration: Calibration, session: CalibrationSession) -> CalibrationMetrics:
    """Errors of ``calibration`` on ``session`` (use a held-out one)."""
    pred = calibration.predict(session.psi)
    err = np.rad2deg(pred - session.theta)
    pinch = session.pinch
    gap = gap_errors_mm(session.theta[pinch], pred[pinch], session.person)
    return CalibrationMetrics(
        n=len(session),
        n_pinch=int(pinch.sum()),
        rms_deg=float(_rms(err)),
        free_rms_deg=float(_rms(err[~pinch])),
        pinch_rms_deg=float(_rms(err[pinch])),
        pinch_gap_mm=float(_rms(gap)),
        joint_rms_deg=tuple(float(v) for v in _rms(err, axis=0)),
        joint_pinch_rms_deg=tuple(float(v) for v in _rms(err[pinch], axis=0)),
    )


def metrics_table(rows: Mapping[str, CalibrationMetrics]) -> str:
    """A small text table: model, all / free / pinch RMS [deg], pinch gap [mm]."""
    lines = [f"{'model':<22} {'all deg':>8} {'free deg':>9} {'pinch deg':>10} {'gap mm':>7}"]
    for name, m in rows.items():
        lines.append(
            f"{name:<22} {m.rms_deg:>8.2f} {m.free_rms_deg:>9.2f} {m.pinch_rms_deg:>10.2f} "
            f"{m.pinch_gap_mm:>7.2f}"
        )
    return "\n".join(lines)

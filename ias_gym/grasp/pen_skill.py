"""The pen skill of paper sections 3.2 and 4.2: four fingers slide along a pen in turn.

Paper frame (docs/NOTES.md): x along the pen axis, y vertical (gravity along -y), z lateral;
moments about the pen's centre of mass. Finger k touches the pen at

    finger 1: (-phi1, +r, 0) pushing -y    finger 2: (-phi2, -r, 0) pushing +y
    finger 3: (+phi3, -r, 0) pushing +y    finger 4: (+phi4, +r, 0) pushing -y

with wrench columns (normal, t_x, t_z) each, which gives W of eq. (16). During phase i
(``t_{i-1} <= t < t_i``) finger i slides outward by ``alpha_i (t_i - t_{i-1})`` (eq. 17):
fingers 1 and 2 to -x, fingers 3 and 4 to +x. The paper's prose says "to the left" for all
four; this module follows the equation (docs/NOTES.md, "Eq. (17)").

Units are SI here (the paper's cm are converted in :class:`PenSkillParams`' defaults).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ias_gym.grasp.internal_forces import (
    Cone,
    InfeasibleGraspError,
    InternalForceSettings,
    solve_internal_forces,
)
from ias_gym.grasp.wrench_matrix import wrench_matrix

FloatArray = NDArray[np.float64]

N_FINGERS = 4
#: Which way (sign along the pen axis x) each finger moves when it slides outward.
OUTWARD = np.array([-1.0, -1.0, 1.0, 1.0])
#: Which side of the pen each finger touches (+1 top, -1 bottom).
SIDE = np.array([1.0, -1.0, -1.0, 1.0])
CM = 0.01  # [m] per paper cm


@dataclass(frozen=True)
class PenSkillParams:
    """Parameters of the sliding skill, paper section 4.2 (defaults are the paper's)."""

    mu: float = 0.25  # Coulomb friction coefficient [-]
    radius: float = 1.0 * CM  # pen radius r [m]
    length: float = 10.0 * CM  # pen length l [m]
    weight: float = 1.0  # m g [N]
    initial_distances: tuple[float, ...] = (3 * CM, 2 * CM, 2 * CM, 3 * CM)  # l_i [m]
    speeds: tuple[float, ...] = (1 * CM, 1 * CM, 1 * CM, 1 * CM)  # alpha_i [m/s]
    phase_times: tuple[float, ...] = (0.0, 1.0, 2.0, 3.0, 4.0)  # t_0..t_4 [s]
    f0: float = 0.1  # minimum normal force, eq. (19) [N]

    def __post_init__(self) -> None:
        if len(self.initial_distances) != N_FINGERS or len(self.speeds) != N_FINGERS:
            raise ValueError("initial_distances and speeds need one entry per finger (4)")
        if len(self.phase_times) != N_FINGERS + 1 or np.any(np.diff(self.phase_times) <= 0):
            raise ValueError(f"phase_times must be 5 increasing times, got {self.phase_times}")
        if min(self.speeds) < 0:
            raise ValueError("eq. (17) needs alpha_i >= 0")

    @property
    def duration(self) -> float:
        """End of the last phase, t_4 [s]."""
        return float(self.phase_times[-1])


def finger_distances(t: ArrayLike, params: PenSkillParams = PenSkillParams()) -> FloatArray:
    """phi_i(t) of eq. (17): each finger's distance from the centre of mass [m].

    Args:
        t: time(s) [s], scalar or array of shape (T,).

    Returns:
        ``(4,)`` for scalar t, else ``(T, 4)``.
    """
    t_arr = np.asarray(t, dtype=float)
    ts = np.asarray(params.phase_times)
    start, end = ts[:-1], ts[1:]
    elapsed = np.clip(t_arr[..., None] - start, 0.0, end - start)
    return np.asarray(params.initial_distances) + np.asarray(params.speeds) * elapsed


def finger_velocities(t: ArrayLike, params: PenSkillParams = PenSkillParams()) -> FloatArray:
    """d phi_i / dt of eq. (17) [m/s] (alpha_i inside phase i, zero elsewhere)."""
    t_arr = np.asarray(t, dtype=float)[..., None]
    ts = np.asarray(params.phase_times)
    active = (t_arr >= ts[:-1]) & (t_arr < ts[1:])
    return np.asarray(params.speeds) * active


def sliding_finger(t: float, params: PenSkillParams = PenSkillParams()) -> int | None:
    """Index (0-based) of the finger sliding at time t, or None outside [t_0, t_4)."""
    ts = params.phase_times
    for i in range(N_FINGERS):
        if ts[i] <= t < ts[i + 1] and params.speeds[i] > 0:
            return i
    return None


def contact_points(phi: ArrayLike, radius: float) -> FloatArray:
    """Contact points (4, 3) [m] in the paper frame for finger distances phi [m]."""
    phi = np.asarray(phi, dtype=float)
    return np.stack([OUTWARD * phi, SIDE * radius, np.zeros(N_FINGERS)], axis=1)


def contact_frames() -> FloatArray:
    """Contact frames (4, 3, 3): rows normal (finger pushes along it), t_x, t_z."""
    frames = np.zeros((N_FINGERS, 3, 3))
    frames[:, 0, 1] = -SIDE  # top fingers push down, bottom fingers push up
    frames[:, 1, 0] = 1.0
    frames[:, 2, 2] = 1.0
    return frames


def pen_wrench_matrix(phi: ArrayLike, radius: float = 1.0 * CM) -> FloatArray:
    """W(t) of eq. (16) (docs/NOTES.md's corrected 6 x 12 form) for finger distances phi [m]."""
    return wrench_matrix(contact_points(phi, radius), contact_frames())


def grasp_wrench_matrix(
    contact_x: ArrayLike, sides: ArrayLike, radius: float = 1.0 * CM
) -> FloatArray:
    """W of eq. (16) for a pen held by any hand: ``(6, 3k)`` [-, m].

    Contact i sits at ``(contact_x[i], sides[i] r, 0)`` (paper frame) with the frame of
    :func:`contact_frames` (normal ``-side`` along y, t_x, t_z); for the paper's four fingers
    ``grasp_wrench_matrix(OUTWARD * phi, SIDE)`` is :func:`pen_wrench_matrix`.

    Args:
        contact_x: ``(k,)`` signed contact positions along the pen from its centre [m].
        sides: ``(k,)`` +1 for a finger on top of the pen (pushes down), -1 below.
        radius: pen radius r [m].
    """
    x = np.asarray(contact_x, dtype=float)
    side = np.asarray(sides, dtype=float)
    if x.shape != side.shape or x.ndim != 1:
        raise ValueError(f"contact_x {x.shape} and sides {side.shape} must be equal (k,)")
    points = np.stack([x, side * radius, np.zeros(len(x))], axis=1)
    frames = np.zeros((len(x), 3, 3))
    frames[:, 0, 1] = -side
    frames[:, 1, 0] = 1.0
    frames[:, 2, 2] = 1.0
    return wrench_matrix(points, frames)


def gravity_wrench(weight: float) -> FloatArray:
    """External wrench of eq. (18) on the pen, ``w_g = [0, -m g, 0, 0, 0, 0]`` [N, N m].

    The fingers must supply ``W c = -w_g`` (docs/NOTES.md, "Sign of gravity").
    """
    return np.array([0.0, -weight, 0.0, 0.0, 0.0, 0.0])


def sliding_directions(
    t: float, params: PenSkillParams = PenSkillParams()
) -> dict[int, FloatArray]:
    """Sliding contacts at time t as {finger index: unit direction in (t_x, t_z)}.

    The force a sliding finger exerts on the pen points along the finger's own motion
    relative to the pen (docs/NOTES.md, "Sliding contact"): outward.
    """
    k = sliding_finger(t, params)
    return {} if k is None else {k: np.array([OUTWARD[k], 0.0])}


def wrench_intensities(
    times: ArrayLike,
    params: PenSkillParams = PenSkillParams(),
    cone: Cone = "box",
    margin: float = 0.0,
) -> FloatArray:
    """The reference wrench intensities c(t) of the sliding skill (paper Fig. 8).

    At each time the internal-force problem of eqs. (19)-(24) is solved for W(t) of eq. (16),
    the weight of eq. (18) and the finger sliding at t (docs/NOTES.md's equality model).

    Args:
        times: ``(T,)`` sample times [s].
        params: skill parameters (the paper's by default).
        cone: ``"box"`` (the paper's LP, HiGHS) or ``"exact"`` (Coulomb cones, Clarabel).
        margin: friction safety margin for the sticking contacts [-].

    Returns:
        ``(T, 12)`` intensities [N], numbered as the paper: finger k has c_{3k-2} normal,
        c_{3k-1} along the pen axis x and c_{3k} along z.

    Raises:
        InfeasibleGraspError: at a time where no intensities hold the pen (names the time).
    """
    settings = InternalForceSettings(mu=params.mu, f0=params.f0, cone=cone, margin=margin)
    w_g = gravity_wrench(params.weight)
    ts = np.atleast_1d(np.asarray(times, dtype=float))
    phis = finger_distances(ts, params)
    out = np.empty((len(ts), 3 * N_FINGERS))
    for row, (t, phi) in enumerate(zip(ts, phis, strict=True)):
        W = pen_wrench_matrix(phi, params.radius)
        try:
            out[row] = solve_internal_forces(W, w_g, sliding_directions(t, params), settings).c
        except InfeasibleGraspError as exc:
            raise InfeasibleGraspError(f"at t = {t:.3f} s: {exc}") from exc
    return out

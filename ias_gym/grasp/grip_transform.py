"""The grip transform G of paper section 3.1, eqs. (4)-(15).

For ``n`` wrench intensities ``c`` acting through the wrench matrix ``W`` (6 x n, eq. 3):

- ``W+ = W^T (W W^T)^-1`` is the right generalised inverse (eq. 5), ``c_p = W+ f_ext``;
- ``N`` (n x (n-6)) is an orthonormal basis of null(W) (eq. 6), ``c_h = N f_int`` (eq. 7);
- ``inv(G^T) = [W; N^T]`` (eq. 8), so that ``F = [f_ext; f_int] = inv(G^T) c`` (eq. 10) and
  ``c = G^T F = [W+ N] F`` (eq. 11);
- twists: ``d = G^-1 v = [W^T N] v`` (eq. 12) and ``v = G d = [(W^T)+; N^T] d`` (eq. 13), with
  ``v = [v_ext; v_int]`` (eq. 14). Power is preserved: ``c . d = F . v``.

The paper's "grip transform" G is a 12 x 12 change of coordinates; the paper's W is what the
modern literature calls the *grasp matrix*.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ias_gym.errors import (
    GraspRankError,
)

FloatArray = NDArray[np.float64]

#: Relative singular-value threshold below which W is treated as rank deficient.
RANK_RTOL = 1e-9


def _checked_wrench_matrix(W: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Validate W and return it with its SVD factors ``U, s`` (s descending)."""
    W = np.asarray(W, dtype=float)
    if W.ndim != 2 or W.shape[0] != 6:
        raise ValueError(f"W must be a 6 x n matrix, got shape {W.shape}")
    if not np.all(np.isfinite(W)):
        raise ValueError("W contains NaN or inf")
    if W.shape[1] < 6:
        raise GraspRankError(
            f"W has only {W.shape[1]} wrench columns; rank W = 6 needs at least 6 (eq. 3)"
        )
    U, s, _ = np.linalg.svd(W, full_matrices=False)
    rank = int(np.sum(s > RANK_RTOL * s[0])) if s[0] > 0 else 0
    if rank < 6:
        raise GraspRankError(
            f"rank W = {rank} < 6: the contacts cannot balance every external wrench "
            f"(singular values {np.array2string(s, precision=3)}); the grip transform of "
            "eq. (8) needs rank W = 6"
        )
    return W, U, s


def pseudo_inverse(W: ArrayLike, *, least_squares_if_singular: bool = False) -> FloatArray:
    """Right generalised inverse ``W+ = W^T (W W^T)^-1`` of eq. (5).

    Args:
        W: the 6 x n wrench matrix [1, m].
        least_squares_if_singular: for a controller's every step: skip the rank check (an
            SVD) and, where ``W W^T`` cannot be inverted (a grasp that lost fingers has zero
            columns), return the least-squares inverse ``np.linalg.pinv(W)`` instead of
            raising.

    Raises:
        GraspRankError: if rank W < 6, with the rank in the message (unless
            ``least_squares_if_singular``).
        ValueError: if W is not 6 x n, or (with the check) holds NaN or inf.
    """
    if least_squares_if_singular:
        W = np.asarray(W, dtype=float)
        if W.ndim != 2 or W.shape[0] != 6:
            raise ValueError(f"W must be a 6 x n matrix, got shape {W.shape}")
        try:
            return _right_inverse(W)
        except np.linalg.LinAlgError:
            return np.linalg.pinv(W).astype(np.float64)
    W, _, _ = _checked_wrench_matrix(W)
    return _right_inverse(W)


def _right_inverse(W: FloatArray) -> FloatArray:
    """``W^T (W W^T)^-1`` (eq. 5); raises ``LinAlgError`` where ``W W^T`` is singular."""
    result: FloatArray = W.T @ np.linalg.inv(W @ W.T)
    return result


def null_space_basis(W: ArrayLike, previous: ArrayLike | None = None) -> FloatArray:
    """Orthonormal basis N of null(W), eq. (6): ``W N = 0``, ``N^T N = I``.

    Any orthonormal basis is valid, which is a problem along a trajectory: an SVD may rotate
    or flip the basis from one time step to the next, so ``f_int = N^T c`` and ``dN/dt`` jump.
    Given the basis of the previous step, the returned basis is the one closest to it
    (orthogonal Procrustes), which makes ``N(t)`` as smooth as ``W(t)``.

    Args:
        W: the 6 x n wrench matrix.
        previous: optional n x (n-6) basis of a nearby W to stay close to.
    """
    W, _, _ = _checked_wrench_matrix(W)
    n = W.shape[1]
    _, _, Vt = np.linalg.svd(W)
    N = Vt[6:].T  # rows 6.. of V^T span null(W) because rank W = 6
    if previous is not None:
        P = np.asarray(previous, dtype=float)
        if P.shape != (n, n - 6):
            raise ValueError(f"previous basis must have shape {(n, n - 6)}, got {P.shape}")
        # Rotate N within null(W) to best match the previous basis: argmin_Q ||N Q - P||.
        U, _, Vt_q = np.linalg.svd(N.T @ P)
        N = N @ (U @ Vt_q)
    return N


@dataclass(frozen=True)
class GripTransform:
    """The grip transform of eq. (8) for one wrench matrix W.

    Build it with :meth:`from_wrench_matrix`. Attributes are the paper's blocks; the
    properties assemble G and its relatives.

    Attributes:
        W: 6 x n wrench matrix (eq. 3).
        W_pinv: n x 6 right generalised inverse ``W+`` (eq. 5).
        N: n x (n-6) orthonormal null-space basis (eq. 6).
    """

    W: FloatArray
    W_pinv: FloatArray
    N: FloatArray

    @classmethod
    def from_wrench_matrix(
        cls, W: ArrayLike, previous: GripTransform | None = None
    ) -> GripTransform:
        """Grip transform of W; ``previous`` keeps N continuous along a trajectory."""
        W, _, _ = _checked_wrench_matrix(W)
        N = null_space_basis(W, None if previous is None else previous.N)
        return cls(W=W, W_pinv=_right_inverse(W), N=N)

    @property
    def n(self) -> int:
        """Number of wrench intensities."""
        return int(self.W.shape[1])

    @property
    def G_T(self) -> FloatArray:
        """``G^T = [W+ N]`` (eq. 11), n x n."""
        return np.hstack([self.W_pinv, self.N])

    @property
    def G_T_inv(self) -> FloatArray:
        """``inv(G^T) = [W; N^T]`` (eq. 8), n x n."""
        return np.vstack([self.W, self.N.T])

    @property
    def G(self) -> FloatArray:
        """``G = [(W^T)+; N^T]`` (eq. 13), n x n."""
        return self.G_T.T

    @property
    def G_inv(self) -> FloatArray:
        """``G^-1 = [W^T N]`` (eq. 12), n x n."""
        return np.hstack([self.W.T, self.N])

    def split(self, c: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """``c = c_p + c_h`` (eq. 4) with ``c_p = W+ W c`` (eq. 5) and ``c_h = N N^T c`` (eq. 7).

        The two parts are orthogonal and ``W c_h = 0``.
        """
        c = np.asarray(c, dtype=float)
        c_p = self.W_pinv @ (self.W @ c)
        return c_p, c - c_p

    def generalized_force(self, c: ArrayLike) -> FloatArray:
        """``F = [f_ext; f_int] = inv(G^T) c`` (eqs. 9, 10)."""
        return self.G_T_inv @ np.asarray(c, dtype=float)

    def intensities(self, F: ArrayLike) -> FloatArray:
        """``c = G^T F = W+ f_ext + N f_int`` (eq. 11)."""
        F = np.asarray(F, dtype=float)
        return self.W_pinv @ F[:6] + self.N @ F[6:]

    def internal_forces(self, c: ArrayLike) -> FloatArray:
        """``f_int = N^T c``: the internal grasp-force magnitudes (eqs. 7, 10)."""
        return self.N.T @ np.asarray(c, dtype=float)

    def twist_intensities(self, v: ArrayLike) -> FloatArray:
        """``d = G^-1 v = W^T v_ext + N v_int`` (eq. 12)."""
        v = np.asarray(v, dtype=float)
        return self.W.T @ v[:6] + self.N @ v[6:]

    def object_velocity(self, d: ArrayLike) -> FloatArray:
        """``v = [v_ext; v_int] = G d`` (eq. 13)."""
        return self.G @ np.asarray(d, dtype=float)

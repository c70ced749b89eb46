"""What a skill is: its model (the dynamics of G(t), Proposition 1) and its demonstration.

:class:`Skill` bundles a :class:`SkillModel` (contact schedule, object trajectory, wrench
intensities ``c``, ``c_h``, ``f_ext = W c``, ``f_int = N^T c``; ``T + 1`` samples) with the
:class:`Demonstration` it was analysed from (Minari's layout) and its provenance. These are
plain, validated containers; :mod:`ias_gym.skills.db` stores them.
:class:`SkillModelSamples` collects a :class:`SkillModel` one sample at a time (the base of
the recorders in :mod:`ias_gym.skills.record` and :mod:`ias_gym.skills.glove_session`).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ias_gym.glove.ids import check_id

if TYPE_CHECKING:
    from ias_gym.sim.pen_hand import FreePenPhysics

#: dtype kinds an array may have: bool, signed and unsigned integers, floats.
SAFE_KINDS = frozenset("biuf")

DEMO_ARRAYS: tuple[str, ...] = (
    "observations",
    "actions",
    "rewards",
    "terminations",
    "truncations",
)
MODEL_ARRAYS: tuple[str, ...] = (
    "time",
    "touching",
    "sliding",
    "pen_position",
    "pen_rpy",
    "pen_velocity",
    "pen_omega",
    "c",
    "c_h",
    "f_ext",
    "f_int",
)


@dataclass(frozen=True, eq=False)
class Demonstration:
    """One episode as a learning agent sees it (Minari's layout).

    Attributes:
        observations: ``(T + 1, ...)``: the reset observation, then one per step.
        actions: ``(T, ...)`` actions passed to ``env.step``.
        rewards: ``(T,)`` float rewards.
        terminations, truncations: ``(T,)`` bool; only the last step may be True.
        infos: name -> ``(T + 1, ...)`` numeric or bool array (reset info, then each step's).
    """

    observations: NDArray[Any]
    actions: NDArray[Any]
    rewards: NDArray[Any]
    terminations: NDArray[np.bool_]
    truncations: NDArray[np.bool_]
    infos: Mapping[str, NDArray[Any]] = field(default_factory=dict)

    @property
    def length(self) -> int:
        """Number of steps T."""
        return len(self.actions)

    @property
    def episode_return(self) -> float:
        """Undiscounted sum of the rewards."""
        return float(np.sum(self.rewards, dtype=np.float64))

    def validate(self) -> None:
        """Check shapes, dtypes and values.

        Raises:
            ValueError: saying which array is wrong and how.
        """
        arrays = {name: getattr(self, name) for name in DEMO_ARRAYS}
        for name, value in arrays.items():
            check_storable_array(f"demonstration.{name}", value)
        T = len(self.actions)
        if T == 0:
            raise ValueError("empty episode: a demonstration needs at least one step (0 actions)")
        if self.observations.ndim < 1 or len(self.observations) != T + 1:
            raise ValueError(
                f"observations must have T + 1 = {T + 1} rows (reset + one per step) for "
                f"{T} actions, got shape {self.observations.shape}"
            )
        for name in ("rewards", "terminations", "truncations"):
            if arrays[name].shape != (T,):
                raise ValueError(f"{name} must have shape ({T},), got {arrays[name].shape}")
        for name in ("terminations", "truncations"):
            if arrays[name].dtype != np.bool_:
                raise ValueError(f"{name} must be a bool array, got dtype {arrays[name].dtype}")
        if arrays["rewards"].dtype.kind != "f":
            raise ValueError(f"rewards must be floats, got dtype {arrays['rewards'].dtype}")
        for name in ("observations", "actions", "rewards"):
            if not np.all(np.isfinite(arrays[name])):
                bad = np.argwhere(~np.isfinite(arrays[name]))[0].tolist()
                raise ValueError(
                    f"{name} contain NaN or inf (first at index {bad}); demonstrations must "
                    "be finite"
                )
        if np.any(self.terminations[:-1] | self.truncations[:-1]):
            first = int(np.flatnonzero(self.terminations[:-1] | self.truncations[:-1])[0])
            raise ValueError(
                f"step {first} of {T} is terminal or truncated: an episode ends at its first "
                "termination or truncation"
            )
        for key, value in self.infos.items():
            if not isinstance(key, str) or not key:
                raise ValueError(f"info names must be non-empty strings, got {key!r}")
            check_storable_array(f"infos[{key!r}]", value)
            if value.ndim < 1 or len(value) != T + 1:
                raise ValueError(
                    f"infos[{key!r}] must have T + 1 = {T + 1} rows (reset + one per step), "
                    f"got shape {value.shape}"
                )


@dataclass(frozen=True, eq=False)
class SkillModel:
    """The paper's skill model (sec. 3): contact schedule, object motion and G(t) along a skill.

    One sample per observation of the demonstration (``T + 1`` rows); paper frame, SI units.

    Attributes:
        time: ``(T + 1,)`` time since reset [s].
        touching: ``(T + 1, k)`` bool, fingertip i touches the object.
        sliding: ``(T + 1, k)`` bool, fingertip i is scheduled to slide (eq. 20).
        pen_position: ``(T + 1, 3)`` object centre r relative to its nominal position [m].
        pen_rpy: ``(T + 1, 3)`` roll, pitch, yaw phi [rad] (eq. 25).
        pen_velocity: ``(T + 1, 3)`` linear velocity v [m/s] (eq. 15).
        pen_omega: ``(T + 1, 3)`` angular velocity omega [rad/s] (eq. 15).
        c: ``(T + 1, n)`` measured wrench intensities [N] (eq. 3).
        c_h: ``(T + 1, n)`` homogeneous (internal) part ``N N^T c`` [N] (eqs. 4, 7); NaN where
            rank W < 6.
        f_ext: ``(T + 1, 6)`` the contacts' net wrench ``W c`` [N, N m] (eq. 3).
        f_int: ``(T + 1, n - 6)`` internal forces ``N^T c`` [N] (eqs. 7, 10); NaN where
            rank W < 6. N is kept continuous along the skill (see ``null_space_basis``).

    Glove sessions are a two-finger pinch recorded with soft-finger contacts (k = 2,
    four intensities per finger: normal, t1, t2 [N] and the torsion about the normal
    [N m]; n = 8): W (eq. 16 with the torsion column ``[0; n]``) is 6 x 8 of rank 6 while
    both touch, G exists, and ``f_int`` has two columns, the squeeze and the opposed
    torsions (:func:`ias_gym.sim.soft_finger.pinch_null_basis`). The one exception is
    the hard-finger pinch stored by older versions (k = 2 point contacts with friction,
    n = 6, :attr:`is_pinch`): its W has rank 5 at best, G (eq. 8) never exists, and null(W)
    is the one squeeze along the line between the contacts; ``f_int`` is then
    ``(T + 1, 1)`` and ``c_h``, ``f_int`` are NaN where rank W < 5 (see
    :func:`ias_gym.sim.soft_finger.squeeze_null_vector`).
    """

    time: NDArray[np.float64]
    touching: NDArray[np.bool_]
    sliding: NDArray[np.bool_]
    pen_position: NDArray[np.float64]
    pen_rpy: NDArray[np.float64]
    pen_velocity: NDArray[np.float64]
    pen_omega: NDArray[np.float64]
    c: NDArray[np.float64]
    c_h: NDArray[np.float64]
    f_ext: NDArray[np.float64]
    f_int: NDArray[np.float64]

    @property
    def c_p(self) -> NDArray[np.float64]:
        """The particular part ``c_p = c - c_h = W+ W c`` [N] (eqs. 4, 5)."""
        return self.c - self.c_h

    @property
    def is_pinch(self) -> bool:
        """Two point contacts with friction (k = 2, n = 6, the hard-finger pinch of older
        glove sessions): rank W <= 5, one internal force. A soft-finger pinch (n = 8) is
        not: its G exists."""
        return self.touching.shape[1:] == (2,) and self.c.shape[1:] == (6,)

    @property
    def duration(self) -> float:
        """Time spanned by the samples [s]."""
        return float(self.time[-1] - self.time[0])

    def validate(self, samples: int | None = None) -> None:
        """Check shapes, dtypes and values.

        Args:
            samples: the number of samples required (``T + 1`` of the demonstration).

        Raises:
            ValueError: saying which array is wrong and how.
        """
        for name in MODEL_ARRAYS:
            check_storable_array(f"model.{name}", getattr(self, name))
        S = len(self.time) if samples is None else samples
        if self.time.shape != (S,):
            raise ValueError(f"model.time must have shape ({S},), got {self.time.shape}")
        k = self.touching.shape[1] if self.touching.ndim == 2 else -1
        n = self.c.shape[1] if self.c.ndim == 2 else -1
        pinch = self.is_pinch
        expected = {
            "touching": (S, k),
            "sliding": (S, k),
            "pen_position": (S, 3),
            "pen_rpy": (S, 3),
            "pen_velocity": (S, 3),
            "pen_omega": (S, 3),
            "c": (S, n),
            "c_h": (S, n),
            "f_ext": (S, 6),
            "f_int": (S, 1 if pinch else n - 6),
        }
        if k < 1 or (n < 7 and not pinch):
            raise ValueError(
                f"model.touching must be (samples, fingers) and model.c (samples, n >= 7), "
                f"or (samples, 2) and (samples, 6) for a pinch, got {self.touching.shape} "
                f"and {self.c.shape}"
            )
        for name, shape in expected.items():
            value = getattr(self, name)
            if value.shape != shape:
                raise ValueError(f"model.{name} must have shape {shape}, got {value.shape}")
        for name in ("touching", "sliding"):
            if getattr(self, name).dtype != np.bool_:
                raise ValueError(f"model.{name} must be bool, got {getattr(self, name).dtype}")
        for name in ("time", "pen_position", "pen_rpy", "pen_velocity", "pen_omega", "c", "f_ext"):
            if not np.all(np.isfinite(getattr(self, name))):
                raise ValueError(f"model.{name} contains NaN or inf; it must be finite")
        if S > 1 and not np.all(np.diff(self.time) > 0):
            raise ValueError("model.time must increase strictly")

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary: duration, contact schedule, force ranges, object excursion.

        Returns:
            ``duration`` [s]; per finger ``fingers[i]`` with the fraction of samples
            touching, the touching and sliding intervals ``[t_start, t_end]`` [s] and the
            normal-force range [N] (column ``3 i`` of c, ``4 i`` for soft fingers); the
            range of each internal force ``f_int`` [N] and of ``|c_h|`` [N] over samples
            where G is defined (for a pinch: where its squeeze is;
            ``grip_transform_defined_fraction`` then counts those samples); the largest
            pen excursion [m] and the range of roll/pitch/yaw [rad].
        """
        k = self.touching.shape[1]
        n = self.c.shape[1]
        fingers = []
        for i in range(k):
            entry: dict[str, Any] = {
                "finger": i + 1,
                "touching_fraction": float(np.mean(self.touching[:, i])),
                "touching": _intervals(self.time, self.touching[:, i]),
                "sliding": _intervals(self.time, self.sliding[:, i]),
            }
            per = n // k if n % k == 0 else 0
            if per in (3, 4):  # 3 (eq. 16) or 4 (soft finger) per finger: normal first
                normal = self.c[:, per * i]
                entry["normal_force_range"] = [float(normal.min()), float(normal.max())]
            fingers.append(entry)
        defined = np.all(np.isfinite(self.f_int), axis=1)
        f_int = self.f_int[defined]
        c_h_norm = np.linalg.norm(self.c_h[defined], axis=1)
        excursion = np.linalg.norm(self.pen_position, axis=1)
        return {
            "duration": self.duration,
            "samples": len(self.time),
            "grip_transform_defined_fraction": float(np.mean(defined)),
            "fingers": fingers,
            "f_int_range": _ranges(f_int),
            "c_h_norm_range": _range(c_h_norm),
            "max_pen_excursion": float(excursion.max()),
            "pen_rpy_range": _ranges(self.pen_rpy),
        }


class SkillModelSamples:
    """The rows of a :class:`SkillModel` as they are sampled, one per observation.

    The base of the skill-model recorders: a subclass's ``sample(env)`` reads the contacts
    and forces of one instant and passes them to :meth:`_append`, which also reads the
    pen's state; :meth:`model` stacks the rows.
    """

    def __init__(self) -> None:
        self._rows: dict[str, list[NDArray[Any]]] = {}

    def _append(
        self,
        *,
        time: float,
        pen: FreePenPhysics,
        W: NDArray[np.float64],
        touching: NDArray[np.bool_],
        sliding: NDArray[np.bool_] | None = None,
        c: NDArray[np.float64],
        c_h: NDArray[np.float64],
        f_int: NDArray[np.float64],
    ) -> None:
        """Append one sample; the pen's pose (eq. 25) and twist (eq. 15) are read from ``pen``.

        Args:
            time: time since reset [s].
            pen: the scene's physics, after the forward pass of this sample.
            W: ``(6, n)`` wrench matrix (eq. 3); ``f_ext = W c`` is stored.
            touching, sliding: ``(k,)`` per finger, touches the pen / is scheduled to slide
                (``None``: no finger is).
            c, c_h: ``(n,)`` measured intensities and their homogeneous part [N].
            f_int: internal forces [N] (NaN where they are not defined).
        """
        position, rpy = pen.pen_pose()
        velocity, omega = pen.pen_twist()
        row = {
            "time": np.float64(time),
            "touching": np.asarray(touching, dtype=bool),
            "sliding": np.zeros(len(touching), dtype=bool) if sliding is None else sliding,
            "pen_position": position,
            "pen_rpy": rpy,
            "pen_velocity": velocity,
            "pen_omega": omega,
            "c": c,
            "c_h": c_h,
            "f_ext": W @ c,
            "f_int": f_int,
        }
        # Copies: a stored row must not change when the caller later writes to an array.
        for key, value in row.items():
            self._rows.setdefault(key, []).append(np.array(value, copy=True))

    def __len__(self) -> int:
        """Number of samples so far."""
        return len(self._rows.get("time", ()))

    def model(self) -> SkillModel:
        """The samples so far as a :class:`SkillModel`.

        Raises:
            ValueError: nothing was sampled yet.
        """
        if not self._rows:
            raise ValueError("no samples recorded; call sample() after reset and each step")
        return SkillModel(**{key: np.stack(rows) for key, rows in self._rows.items()})


@dataclass(frozen=True, eq=False)
class Skill:
    """A stored skill: its model, its demonstration and where it came from.

    Attributes:
        name: a human-readable name (not unique).
        task: the Gymnasium id of the env the skill was performed in.
        source: ``"expert"``, ``"random"``, ``"policy:<path>"``, ``"glove"``, ...
        demonstration: the episode.
        model: the skill model sampled along the episode.
        is_success: the env's ``is_success`` at the end of the episode.
        seed: the episode's reset seed (``None``: not seeded, e.g. a glove session).
        person_id: who demonstrated it (glove sessions), optional.
        env_kwargs: keyword arguments the env was made with (JSON-serialisable).
        person_params: the demonstrating person's parameters by name, where they are known
            (a simulated person's drawn hand and style:
            :func:`~ias_gym.glove.skills.person_parameters`); ``None`` otherwise (a real
            glove's wearer, a policy).
        id, created, package_version: filled in by the database (``None`` before storing).
    """

    name: str
    task: str
    source: str
    demonstration: Demonstration
    model: SkillModel
    is_success: bool
    seed: int | None = None
    person_id: str | None = None
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    person_params: Mapping[str, float] | None = None
    id: int | None = None
    created: str | None = None
    package_version: str | None = None

    @property
    def length(self) -> int:
        """Number of steps of the demonstration."""
        return self.demonstration.length

    def validate(self) -> None:
        """Check every field.

        Raises:
            ValueError: saying what is wrong (an invalid ``person_id`` or env kwargs
                ``person_id``: :class:`~ias_gym.errors.InputError`, a ValueError).
        """
        for name in ("name", "task", "source"):
            value = getattr(self, name)
            if not isinstance(value, str) or not value.strip():
                raise ValueError(f"skill {name} must be a non-empty string, got {value!r}")
        if self.person_id is not None:
            # person ids name profile files
            check_id(self.person_id, "skill person_id")
        if self.seed is not None and not isinstance(self.seed, (int, np.integer)):
            raise ValueError(f"seed must be an int or None, got {self.seed!r}")
        try:
            json.dumps(dict(self.env_kwargs), allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"env_kwargs must be JSON-serialisable: {exc}") from exc
        if "person_id" in self.env_kwargs:  # re-creating the env would name files with it
            check_id(self.env_kwargs["person_id"], "skill env_kwargs person_id")
        if self.person_params is not None:
            check_person_params(self.person_params)
        self.demonstration.validate()
        self.model.validate(samples=self.demonstration.length + 1)


def check_person_params(value: object, what: str = "skill person_params") -> dict[str, float]:
    """``value`` as a person's parameters: a mapping of non-empty names to finite numbers.

    Raises:
        ValueError: saying which entry is wrong.
    """
    if not isinstance(value, Mapping):
        raise ValueError(
            f"{what} must be a mapping of names to numbers, got {type(value).__name__}"
        )
    out: dict[str, float] = {}
    for key, number in value.items():
        if not isinstance(key, str) or not key:
            raise ValueError(f"{what} names must be non-empty strings, got {key!r}")
        if isinstance(number, bool) or not isinstance(number, (int, float, np.number)):
            raise ValueError(f"{what}[{key!r}] must be a number, got {number!r}")
        if not np.isfinite(number):
            raise ValueError(f"{what}[{key!r}] must be finite, got {number!r}")
        out[key] = float(number)
    return out


def check_storable_array(what: str, value: Any) -> None:
    """Raise ValueError unless ``value`` is a bool, integer or float numpy array."""
    if not isinstance(value, np.ndarray):
        raise ValueError(f"{what} must be a numpy array, got {type(value).__name__}")
    if value.dtype.kind not in SAFE_KINDS:
        raise ValueError(
            f"{what} has dtype {value.dtype}; only bool, integer and float arrays are stored"
        )


def _intervals(time: NDArray[np.float64], flags: NDArray[np.bool_]) -> list[list[float]]:
    """``[[t_start, t_end], ...]`` [s] of the runs where ``flags`` is True."""
    padded = np.concatenate([[False], flags, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    return [
        [float(time[a]), float(time[b - 1])] for a, b in zip(edges[::2], edges[1::2], strict=True)
    ]


def _ranges(values: NDArray[np.float64]) -> list[list[float] | None]:
    """Per column ``[min, max]``; ``None`` for every column when there are no rows."""
    if len(values) == 0:
        return [None] * (values.shape[1] if values.ndim == 2 else 0)
    lo, hi = values.min(axis=0).tolist(), values.max(axis=0).tolist()
    return [[a, b] for a, b in zip(lo, hi, strict=True)]


def _range(values: NDArray[np.float64]) -> list[float] | None:
    """``[min, max]`` of all values, ``None`` if there are none."""
    if values.size == 0:
        return None
    return [float(values.min()), float(values.max())]

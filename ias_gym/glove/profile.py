"""A person's calibration profile: a safe JSON file, written atomically, checked on load.

Paper section 2.4: "for a different person operating the sensor glove a different set of weight
matrices for the ANNs can be used". A profile is that set for one person and one glove: the
:class:`~ias_gym.glove.calibration.Calibration` (every group's normalisation constants and
weights as nested lists, in [rad] and normalised units), who and which glove it is for, when
it was made (UTC ISO 8601), the model kind, the held-out errors and how it was trained.

Format (JSON, UTF-8; plain data only, so loading never executes anything)::

    {"format": "ias-gym/glove-profile", "schema_version": 1,
     "person_id": "p1", "glove_id": "sim-glove-0", "created": "2026-01-01T12:00:00+00:00",
     "model_kind": "ann", "n_readings": 10, "sensor_names": [...], "joint_names": [...],
     "units": "rad",
     "groups": [{"name": "index", "kind": "ann", "inputs": [...], "outputs": [...],
                 "x_mean": [...], "x_scale": [...], "y_mean": [...], "y_scale": [...],
                 "layers": [{"weight": [[...], ...], "bias": [...]}, ...]}, ...],
     "held_out": {"rms_deg": ..., "pinch_rms_deg": ..., "pinch_gap_mm": ..., ...},
     "training": {...}}

Floats are written with Python's shortest round-trip repr, so a loaded profile predicts
bit-identically to the one saved. :func:`save_profile` writes a temporary file in the same
folder, fsyncs it and renames it over the target (``os.replace``), so a reader never sees half
a profile. :func:`load_profile` raises :class:`ProfileError` naming what is wrong (missing,
truncated, not JSON, wrong schema, bad arrays, another glove, another reading count) and
what to do about it.

Numbers a trained calibration cannot hold are refused on load, naming the array: NaN and
inf (also ``1e309``, which JSON parsers read as inf), any weight, bias or mean beyond
+-:data:`MAX_PARAMETER`, and normalisation scales below :data:`MIN_SCALE` (dividing by one
is a weight beyond that bound). Such a profile would drive the hand with overflowing,
NaN joint angles. Person and glove ids must follow :func:`~ias_gym.glove.ids.check_id`
(they name files), on load and when a :class:`Profile` is made.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ias_gym.errors import (
    InputError,
    ProfileError,
)
from ias_gym.glove.calibration import Calibration, CalibrationMetrics, GroupModel
from ias_gym.glove.hand import JOINT_NAMES, N_SENSORS, SENSOR_NAMES
from ias_gym.glove.ids import check_id

FORMAT = "ias-gym/glove-profile"
SCHEMA_VERSION = 1
#: Refuse to parse larger files [bytes] (a profile is a few tens of kB).
MAX_PROFILE_BYTES = 16 * 1024 * 1024
#: The glove id of :class:`~ias_gym.glove.device.SimulatedGlove` unless told otherwise.
DEFAULT_GLOVE_ID = "sim-glove-0"
#: Largest |weight|, |bias| or |mean| a profile may hold (normalised units; [rad] for the
#: means). Trained ones stay below 1e2 (weight decay, z-scored data); 1e6 leaves room.
MAX_PARAMETER = 1e6
#: Smallest normalisation scale [rad] (training uses 1 for a constant column).
MIN_SCALE = 1e-9

_REMEDY = "re-run `ias-gym calibrate --person ID --out DIR` to write a new profile"


def utc_now() -> str:
    """The current time, UTC, ISO 8601 with seconds."""
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


@dataclass(frozen=True, eq=False)
class Profile:
    """One person's calibration for one glove.

    Attributes:
        person_id: whose hand.
        glove_id: which glove (a profile is refused by another glove).
        calibration: the models Θ = f(Ψ).
        held_out: errors on the held-out readings of the calibration session.
        created: UTC ISO 8601 time stamp.
        training: free-form JSON-able facts about the training (seed, readings, seconds).

    Raises:
        InputError: ``person_id`` or ``glove_id`` is not a valid id
            (:func:`~ias_gym.glove.ids.check_id`).
    """

    person_id: str
    glove_id: str
    calibration: Calibration
    held_out: CalibrationMetrics
    created: str = field(default_factory=utc_now)
    training: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        # The ids end up in file names (profile_<person>.json): never save a hostile one.
        check_id(self.person_id, "person_id")
        check_id(self.glove_id, "glove_id")

    @property
    def model_kind(self) -> str:
        """``"ann"`` or ``"linear"``."""
        return self.calibration.kind

    def predict(self, psi: ArrayLike) -> NDArray[np.float64]:
        """Joint angles Θ [rad] from readings Ψ [rad]; see :meth:`Calibration.predict`."""
        return self.calibration.predict(psi)

    def to_json_dict(self) -> dict[str, Any]:
        """The profile as plain JSON data (the file format above)."""
        return {
            "format": FORMAT,
            "schema_version": SCHEMA_VERSION,
            "person_id": self.person_id,
            "glove_id": self.glove_id,
            "created": self.created,
            "model_kind": self.model_kind,
            "n_readings": N_SENSORS,
            "sensor_names": list(SENSOR_NAMES),
            "joint_names": list(JOINT_NAMES),
            "units": "rad",
            "groups": [_group_to_json(g) for g in self.calibration.groups],
            "held_out": self.held_out.to_dict(),
            "training": dict(self.training),
        }


def _group_to_json(g: GroupModel) -> dict[str, Any]:
    return {
        "name": g.name,
        "kind": g.kind,
        "inputs": list(g.inputs),
        "outputs": list(g.outputs),
        "x_mean": g.x_mean.tolist(),
        "x_scale": g.x_scale.tolist(),
        "y_mean": g.y_mean.tolist(),
        "y_scale": g.y_scale.tolist(),
        "layers": [{"weight": w.tolist(), "bias": b.tolist()} for w, b in g.layers],
    }


def write_bytes_atomic(path: Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` via a temporary file in the same folder + ``os.replace``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def save_profile(profile: Profile, path: str | os.PathLike[str]) -> Path:
    """Write ``profile`` to ``path`` (JSON) atomically; returns the path."""
    text = json.dumps(profile.to_json_dict(), indent=1, allow_nan=False)
    return write_bytes_atomic(Path(path), (text + "\n").encode())


def _reject_constant(name: str) -> Any:
    raise ValueError(f"non-finite number {name} (profiles hold finite numbers only)")


class _Checker:
    """Reads fields of the parsed JSON, raising ProfileError with the path and the field."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, what: str, remedy: str = _REMEDY) -> ProfileError:
        return ProfileError(f"glove profile {self.path}: {what}; {remedy}")

    def get(self, d: Mapping[str, Any], key: str, kind: type | tuple[type, ...], where: str) -> Any:
        if key not in d:
            raise self.fail(f"{where} has no {key!r}")
        value = d[key]
        if (isinstance(value, bool) and kind is not bool) or not isinstance(value, kind):
            names = kind.__name__ if isinstance(kind, type) else "/".join(k.__name__ for k in kind)
            raise self.fail(f"{where}.{key} must be {names}, got {type(value).__name__}")
        return value

    def strings(self, d: Mapping[str, Any], key: str, where: str) -> tuple[str, ...]:
        value = self.get(d, key, list, where)
        if not all(isinstance(v, str) for v in value):
            raise self.fail(f"{where}.{key} must be a list of strings")
        return tuple(value)

    def array(
        self, value: Any, ndim: int, where: str, *, scale: bool = False
    ) -> NDArray[np.float64]:
        """``value`` as a float array: ``ndim``-D, finite, |x| <= MAX_PARAMETER, and for a
        normalisation ``scale`` >= MIN_SCALE."""

        def ok(v: Any, depth: int) -> bool:
            if depth == 0:
                return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            return isinstance(v, list) and all(ok(e, depth - 1) for e in v)

        if not ok(value, ndim):
            raise self.fail(f"{where} must be a {ndim}-D list of finite numbers")
        try:
            out = np.array(value, dtype=np.float64)
        except ValueError:  # ragged rows
            raise self.fail(f"{where} has rows of different lengths") from None
        if out.size and float(np.abs(out).max()) > MAX_PARAMETER:
            raise self.fail(
                f"{where} holds {float(out.flat[np.argmax(np.abs(out))]):.6g}, beyond "
                f"+-{MAX_PARAMETER:g}: not a trained calibration (its joint angles would "
                "overflow)"
            )
        if scale and out.size and float(out.min()) < MIN_SCALE:
            raise self.fail(
                f"{where} holds {float(out.min()):.6g}, below {MIN_SCALE:g}: not a trained "
                "calibration (dividing by it overflows the joint angles)"
            )
        return out


def _parse_group(c: _Checker, g: Any, k: int) -> GroupModel:
    where = f"groups[{k}]"
    if not isinstance(g, dict):
        raise c.fail(f"{where} must be an object")
    layers_json = c.get(g, "layers", list, where)
    layers = []
    for i, layer in enumerate(layers_json):
        if not isinstance(layer, dict):
            raise c.fail(f"{where}.layers[{i}] must be an object")
        w = c.array(
            c.get(layer, "weight", list, f"{where}.layers[{i}]"), 2, f"{where}.layers[{i}].weight"
        )
        b = c.array(
            c.get(layer, "bias", list, f"{where}.layers[{i}]"), 1, f"{where}.layers[{i}].bias"
        )
        layers.append((w, b))
    try:
        return GroupModel(
            name=c.get(g, "name", str, where),
            kind=c.get(g, "kind", str, where),
            inputs=c.strings(g, "inputs", where),
            outputs=c.strings(g, "outputs", where),
            x_mean=c.array(c.get(g, "x_mean", list, where), 1, f"{where}.x_mean"),
            x_scale=c.array(c.get(g, "x_scale", list, where), 1, f"{where}.x_scale", scale=True),
            y_mean=c.array(c.get(g, "y_mean", list, where), 1, f"{where}.y_mean"),
            y_scale=c.array(c.get(g, "y_scale", list, where), 1, f"{where}.y_scale", scale=True),
            layers=tuple(layers),
        )
    except (ValueError, KeyError) as exc:
        raise c.fail(f"{where} is not a valid model: {exc}") from None


def _checked_id(c: _Checker, value: str, what: str) -> str:
    try:
        return check_id(value, what)
    except InputError as exc:
        raise c.fail(str(exc)) from None


def profile_from_json_dict(
    data: Any,
    path: Path = Path("<memory>"),
    *,
    glove_id: str | None = None,
    person_id: str | None = None,
    n_readings: int = N_SENSORS,
) -> Profile:
    """Check parsed JSON and build the :class:`Profile` (see :func:`load_profile`)."""
    c = _Checker(path)
    if not isinstance(data, dict):
        raise c.fail(f"the top level must be a JSON object, got {type(data).__name__}")
    if data.get("format") != FORMAT:
        raise c.fail(f"not a glove profile (format {data.get('format')!r}, expected {FORMAT!r})")
    version = c.get(data, "schema_version", int, "profile")
    if version != SCHEMA_VERSION:
        newer = version > SCHEMA_VERSION
        raise c.fail(
            f"schema version {version}, this ias-gym reads version {SCHEMA_VERSION}",
            "upgrade ias-gym to read it" if newer else _REMEDY,
        )
    file_glove = _checked_id(c, c.get(data, "glove_id", str, "profile"), "glove_id")
    if glove_id is not None and file_glove != glove_id:
        raise c.fail(
            f"made for glove {file_glove!r}, not for this glove {glove_id!r}",
            f"calibrate this person on glove {glove_id!r} (a profile fits one glove)",
        )
    file_person = _checked_id(c, c.get(data, "person_id", str, "profile"), "person_id")
    if person_id is not None and file_person != person_id:
        raise c.fail(
            f"belongs to person {file_person!r}, not {person_id!r}", "load their own profile"
        )
    count = c.get(data, "n_readings", int, "profile")
    sensors = c.strings(data, "sensor_names", "profile")
    if count != n_readings or len(sensors) != count:
        raise c.fail(
            f"made for a glove with {count} readings ({len(sensors)} sensor names), "
            f"this glove sends {n_readings}",
            "calibrate again with this glove",
        )
    if sensors != SENSOR_NAMES or c.strings(data, "joint_names", "profile") != JOINT_NAMES:
        raise c.fail(
            "its sensor or joint names differ from this ias-gym's "
            f"({list(SENSOR_NAMES)} -> {list(JOINT_NAMES)})"
        )
    created = c.get(data, "created", str, "profile")
    try:
        datetime.fromisoformat(created)
    except ValueError:
        raise c.fail(f"created {created!r} is not an ISO 8601 time") from None
    groups = c.get(data, "groups", list, "profile")
    try:
        calibration = Calibration(tuple(_parse_group(c, g, k) for k, g in enumerate(groups)))
    except ValueError as exc:
        if isinstance(exc, ProfileError):
            raise
        raise c.fail(f"its groups do not form a calibration: {exc}") from None
    kind = c.get(data, "model_kind", str, "profile")
    if kind != calibration.kind:
        raise c.fail(f"model_kind {kind!r} but the groups make a {calibration.kind!r} model")
    try:
        held_out = CalibrationMetrics.from_dict(c.get(data, "held_out", dict, "profile"))
    except (KeyError, TypeError, ValueError) as exc:
        raise c.fail(f"held_out errors incomplete ({exc})") from None
    training = c.get(data, "training", dict, "profile")
    return Profile(file_person, file_glove, calibration, held_out, created, training)


def load_profile(
    path: str | os.PathLike[str],
    *,
    glove_id: str | None = None,
    person_id: str | None = None,
    n_readings: int = N_SENSORS,
) -> Profile:
    """Load and check a profile.

    Args:
        path: the JSON file.
        glove_id: if given, the profile must be for this glove.
        person_id: if given, the profile must be this person's.
        n_readings: readings the glove sends (10 for the paper's glove).

    Raises:
        ProfileError: missing, unreadable, truncated or malformed file, unknown schema
            version, non-finite or absurd numbers (the message names the array), an
            invalid person or glove id, or a profile for another glove, person or reading
            count.
    """
    p = Path(path)
    c = _Checker(p)
    try:
        size = p.stat().st_size
        if size > MAX_PROFILE_BYTES:
            raise c.fail(f"{size} bytes, more than a profile can be ({MAX_PROFILE_BYTES})")
        raw = p.read_bytes()
    except FileNotFoundError:
        raise c.fail("no such file", f"create it: {_REMEDY}") from None
    except OSError as exc:
        raise c.fail(f"cannot be read ({exc.strerror})", "check the path and permissions") from None
    try:
        data = json.loads(raw.decode("utf-8"), parse_constant=_reject_constant)
    except UnicodeDecodeError:
        raise c.fail("is not UTF-8 text (corrupted?)") from None
    except json.JSONDecodeError as exc:
        raise c.fail(
            f"is not valid JSON ({exc.msg} at line {exc.lineno} column {exc.colno}; "
            "truncated or corrupted?)"
        ) from None
    except ValueError as exc:
        raise c.fail(str(exc)) from None
    return profile_from_json_dict(
        data, p, glove_id=glove_id, person_id=person_id, n_readings=n_readings
    )

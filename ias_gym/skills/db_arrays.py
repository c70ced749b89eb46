"""Array storage of the skill database: raw bytes with dtype, shape and a SHA-256 checksum.

Arrays are stored as raw bytes with their dtype (``numpy.dtype.str``, byte order included)
and shape in their own columns; loading uses ``numpy.frombuffer``. Nothing is pickled and
only numeric and bool dtypes are accepted, so a database file cannot run code. The checksum
(:func:`array_checksum`) covers dtype, shape and bytes. Split out of
:mod:`ias_gym.skills.db`, which re-exports :func:`array_checksum`.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ias_gym.skills.db_sqlite import SkillDBError
from ias_gym.skills.skill import SAFE_KINDS, check_storable_array


def array_checksum(dtype: str, shape: str, data: bytes) -> str:
    """``"sha256:<hex>"`` of a stored array: its dtype string, shape JSON and raw bytes.

    The dtype and shape are hashed too (NUL-separated), so a changed byte order or shape
    is caught like a changed number.
    """
    digest = hashlib.sha256()
    digest.update(dtype.encode())
    digest.update(b"\0")
    digest.update(shape.encode())
    digest.update(b"\0")
    digest.update(data)
    return "sha256:" + digest.hexdigest()


def _initial_observation_checksum(data: bytes) -> str:
    return array_checksum("<f8", json.dumps([len(data) // 8]), data)


def _encode(value: NDArray[Any]) -> tuple[str, str, bytes, str]:
    """``(dtype, shape, bytes, checksum)`` of an array: C order, byte order kept in the
    dtype string."""
    check_storable_array("array", value)
    data = np.ascontiguousarray(value)
    dtype, shape, raw = data.dtype.str, json.dumps(list(data.shape)), data.tobytes()
    return dtype, shape, raw, array_checksum(dtype, shape, raw)


def _decode(
    path: Path, skill_id: int, what: str, dtype: str, shape: str, data: bytes
) -> NDArray[Any]:
    try:
        dt = np.dtype(dtype)
        dims = tuple(int(d) for d in json.loads(shape))
    except (TypeError, ValueError) as exc:
        raise SkillDBError(f"skill {skill_id} in {path}: {what} has a bad dtype/shape") from exc
    if dt.kind not in SAFE_KINDS:
        raise SkillDBError(f"skill {skill_id} in {path}: {what} has unsafe dtype {dtype!r}")
    expected = dt.itemsize * math.prod(dims)
    if len(data) != expected:
        raise SkillDBError(
            f"skill {skill_id} in {path} is corrupt: {what} holds {len(data)} bytes, "
            f"{dtype}{list(dims)} needs {expected}; delete the skill or restore a backup"
        )
    return np.frombuffer(data, dtype=dt).reshape(dims).copy()

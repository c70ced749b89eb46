"""One rule for the ids of persons and gloves, which end up in file names.

A person id names the cached calibration profile (``<person>-seed<S>.json``) and the files
``ias-gym calibrate`` writes (``profile_<person>.json``, ``calibration_<person>.png``); a
glove id is stored in profiles and skill sources. Both come from users, command lines,
``--env-kwargs``, skill rows and downloaded Minari datasets, so an id like ``/etc/x`` or
``../x`` would otherwise write outside the folder it was meant for. :func:`check_id` is the
one check used wherever such an id enters (env config, :class:`~ias_gym.glove.hand.PersonParams`,
profiles, skills, the commands).

The rule: 1 to :data:`MAX_ID_LENGTH` ASCII letters, digits, ``.``, ``_`` or ``-``, and not
``.`` or ``..`` (the current and the parent directory).
"""

from __future__ import annotations

import re
from typing import Any

from ias_gym.errors import InputError

#: Longest id accepted [characters]: a file name stays far below the usual 255-byte limit.
MAX_ID_LENGTH = 64
#: What an id may be made of (ASCII only: no separators, no NUL, no look-alike letters).
ID_PATTERN = re.compile(r"[A-Za-z0-9._-]+")
#: The rule in words, for error messages and help texts.
ID_RULE = f"1-{MAX_ID_LENGTH} ASCII letters, digits, '.', '_' or '-', and not '.' or '..'"


def check_id(value: Any, what: str = "person_id") -> str:
    """Return ``value`` if it is a valid person or glove id, else raise.

    Args:
        value: the id to check.
        what: how the caller calls it in messages (``"person_id"``, ``"--glove-id"``, ...).

    Returns:
        ``value`` unchanged.

    Raises:
        InputError: ``value`` is not a string, or breaks the rule (:data:`ID_RULE`); the
            message names the value and the rule.
    """
    if not isinstance(value, str):
        raise InputError(f"{what} must be a string ({ID_RULE}), got {type(value).__name__}")
    shown = repr(value if len(value) <= 2 * MAX_ID_LENGTH else value[: 2 * MAX_ID_LENGTH] + "...")
    if len(value) > MAX_ID_LENGTH:
        raise InputError(f"{what} {shown} is {len(value)} characters long; an id is {ID_RULE}")
    if not ID_PATTERN.fullmatch(value) or value in (".", ".."):
        raise InputError(f"{what} {shown} is not a valid id; an id is {ID_RULE}")
    return value

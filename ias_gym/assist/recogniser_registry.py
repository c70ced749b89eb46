"""The recognisers by method name (:data:`METHODS`) and :func:`make_recogniser`, which
builds one on a skill database or on library sessions."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from ias_gym.assist.dtw_recogniser import DTWRecogniser
from ias_gym.assist.phase_recogniser import PhaseRecogniser
from ias_gym.assist.recognition import LibraryRecogniser, LibrarySession, load_library
from ias_gym.errors import InputError

if TYPE_CHECKING:
    from ias_gym.skills import SkillDB

#: The recognisers by method name.
METHODS: dict[str, type[LibraryRecogniser]] = {"dtw": DTWRecogniser, "phase": PhaseRecogniser}


def make_recogniser(method: str, db: SkillDB | Sequence[LibrarySession]) -> LibraryRecogniser:
    """A recogniser of the glove sessions in ``db``.

    Args:
        method: ``"dtw"`` (baseline) or ``"phase"`` (the phase-aware probabilistic model).
        db: an open :class:`~ias_gym.skills.SkillDB`, or library sessions.

    Returns:
        The recogniser.

    Raises:
        InputError: unknown method, or a library it cannot be built from.
    """
    if method not in METHODS:
        raise InputError(
            f"method {method!r} is not a recogniser; choose one of {', '.join(METHODS)}"
        )
    sessions = db if isinstance(db, Sequence) else load_library(db)
    return METHODS[method](sessions)

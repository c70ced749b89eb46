"""The recognisers by method name (:data:`METHODS`) and :func:`make_recogniser`, which
builds one on a skill database or on library sessions."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from ias_gym.assist.dtw_recogniser import DTWRecogniser
from ias_gym.assist.phase_recogniser import PhaseRecogniser
from ias_gym.assist.recognition import LibraryRecogniser, LibrarySession, load_library
from ias_gym.errors import InputError

if TYPE_CHECKING:
    from ias_gym.skills import SkillDB


def _phase_single(sessions: Sequence[LibrarySession]) -> LibraryRecogniser:
    """The phase model with no switches: one skill per session (the switching's ablation)."""
    return PhaseRecogniser(sessions, switch_rate=0.0)


#: The recognisers by method name: the DTW baseline, the phase model, and the phase model
#: without switches between skills (``phase_single``, an ablation).
METHODS: dict[str, Callable[[Sequence[LibrarySession]], LibraryRecogniser]] = {
    "dtw": DTWRecogniser,
    "phase": PhaseRecogniser,
    "phase_single": _phase_single,
}


def make_recogniser(method: str, db: SkillDB | Sequence[LibrarySession]) -> LibraryRecogniser:
    """A recogniser of the glove sessions in ``db``.

    Args:
        method: ``"dtw"`` (baseline), ``"phase"`` (the phase-aware probabilistic model) or
            ``"phase_single"`` (the same, for an operator who never switches skills).
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

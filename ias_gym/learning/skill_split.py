"""Train / held-out split of a human skill library by skill name and by person.

Learning across skills asks two questions of a policy trained on executions of
some people's skills: does it execute the *same* skills when *other* people demonstrate
them (held-out persons), and does it execute skills it never saw (held-out skills)?
:func:`split_skills` puts each stored skill into exactly one of four groups by those two
properties; only the ``train`` group may feed training, and it holds no skill whose name
or person is held out.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from ias_gym.errors import InputError
from ias_gym.skills.db import SkillSummary

#: The four groups, in report order: (person held out?, skill held out?).
GROUPS: tuple[str, ...] = ("train", "heldout_skill", "heldout_person", "heldout_both")


@dataclass(frozen=True)
class SkillSplit:
    """Skill ids of one library per group (each id in exactly one group).

    Attributes:
        train: training persons performing training skills (the only group to train on;
            evaluated on other reset seeds than the training ones).
        heldout_skill: training persons performing held-out skills.
        heldout_person: held-out persons performing training skills.
        heldout_both: held-out persons performing held-out skills.
    """

    train: tuple[int, ...]
    heldout_skill: tuple[int, ...]
    heldout_person: tuple[int, ...]
    heldout_both: tuple[int, ...]

    def group(self, name: str) -> tuple[int, ...]:
        """The ids of group ``name`` (one of :data:`GROUPS`).

        Raises:
            InputError: ``name`` is not a group.
        """
        if name not in GROUPS:
            raise InputError(f"no skill group {name!r}; groups: {', '.join(GROUPS)}")
        ids: tuple[int, ...] = getattr(self, name)
        return ids


def split_skills(
    summaries: Iterable[SkillSummary],
    heldout_skills: Sequence[str],
    heldout_persons: Sequence[str],
) -> SkillSplit:
    """Split a library's glove skills into the four :data:`GROUPS`.

    A skill whose name is in ``heldout_skills`` or whose person is in ``heldout_persons``
    is never in ``train``. Skills without a person (robot executions) and unsuccessful
    sessions are left out: they are not human demonstrations to learn from or test on.

    Args:
        summaries: the library's skills (``SkillDB.list_skills()``).
        heldout_skills: skill names kept out of training.
        heldout_persons: person ids kept out of training.

    Returns:
        The ids per group, each sorted.

    Raises:
        InputError: ``heldout_skills`` or ``heldout_persons`` holds an empty string.
    """
    names, persons = set(heldout_skills), set(heldout_persons)
    if "" in names or "" in persons:
        raise InputError("held-out skill names and person ids must be non-empty strings")
    groups: dict[str, list[int]] = {g: [] for g in GROUPS}
    for s in summaries:
        if not s.person_id or not s.is_success:
            continue
        person_out, skill_out = s.person_id in persons, s.name in names
        key = GROUPS[2 * person_out + skill_out]
        groups[key].append(int(s.id))
    return SkillSplit(*(tuple(sorted(groups[g])) for g in GROUPS))

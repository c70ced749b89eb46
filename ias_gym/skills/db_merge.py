"""Joining skill databases into one new file (``ias-gym skills merge``).

Shards recorded apart (on several machines, or by runs that each wrote their own file)
become one database: every skill of every input, in the order of the inputs and, within
one, of its ids, with its provenance (name, source, person, seed, env kwargs, creation time,
package version) and its arrays bit for bit; the ids are new. Each skill is read through
:meth:`SkillDB.get`, which verifies every array against its checksum, so a corrupt shard
stops the merge naming the skill instead of spreading damage. The output is written into a
temporary file beside it and renamed into place only when complete
(:func:`~ias_gym.outputs.atomic_output`): a reader never sees half a database, and an
existing file is replaced only with ``overwrite``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path

from ias_gym.errors import InputError
from ias_gym.outputs import atomic_output, check_output_file
from ias_gym.skills.db import SkillDB


def merge_databases(
    out: str | Path, sources: Sequence[str | Path], *, overwrite: bool = False
) -> list[int]:
    """Write every skill of ``sources`` into the new database ``out``, atomically.

    Args:
        out: the merged database file (its directory must exist).
        sources: the databases to join (read-only; each at most once).
        overwrite: replace an existing ``out`` (it may be one of the sources: they are read
            completely before it is replaced).

    Returns:
        How many skills came from each source, in order.

    Raises:
        InputError: no sources, a source given twice, an unusable ``out`` path, or ``out``
            has a non-empty write-ahead log beside it (it is open, or was not closed
            cleanly: the log would be applied to the new file).
        OutputExistsError: ``out`` exists and ``overwrite`` is false.
        SkillDBError: a source is missing, not a skill database, predates checksums (run
            ``ias-gym skills migrate`` on it), or a skill fails its checksums.
    """
    if not sources:
        raise InputError("skills merge needs at least one database to read")
    paths = [Path(s) for s in sources]
    seen: dict[Path, Path] = {}
    for path in paths:
        key = path.resolve()
        if key in seen:
            raise InputError(f"{path} is given twice (as {seen[key]}); its skills would be doubled")
        seen[key] = path
    out = check_output_file(out, overwrite=overwrite, what="--out")
    wal = out.with_name(out.name + "-wal")
    if wal.exists() and wal.stat().st_size > 0:  # readers leave an empty one: harmless
        raise InputError(
            f"{wal} holds a write-ahead log: {out} is open in another process or was not "
            "closed cleanly, and the log would be applied to the new file; close it (open "
            "and close it once for writing) before replacing it"
        )
    for path in paths:  # every source opens before anything is written
        SkillDB(path, readonly=True).close()
    counts: list[int] = []
    with atomic_output(out, overwrite=overwrite) as tmp:
        with SkillDB(tmp) as merged:
            for path in paths:
                with SkillDB(path, readonly=True) as source:
                    ids = source.ids()
                    for skill_id in ids:
                        skill = source.get(skill_id)  # verifies every array's checksum
                        merged.add(dataclasses.replace(skill, id=None))
                counts.append(len(ids))
    return counts


__all__ = ["merge_databases"]

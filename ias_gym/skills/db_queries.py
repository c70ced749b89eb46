"""The reads of the skill database: :class:`SkillSummary` rows and the queries of
:class:`~ias_gym.skills.db.SkillDB` (list, get with checksum verification, check, nearest
initial state), as the mixin :class:`SkillQueries` that ``SkillDB`` inherits.

Split out of :mod:`ias_gym.skills.db` (which re-exports :class:`SkillSummary`); the mixin
uses the connection, the error translation and the transactions ``SkillDB`` provides.
"""

from __future__ import annotations

import dataclasses
import json
import sqlite3
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ias_gym.skills.db_arrays import _decode, array_checksum
from ias_gym.skills.db_sqlite import SkillDBError, SkillNotFoundError
from ias_gym.skills.skill import (
    DEMO_ARRAYS,
    MODEL_ARRAYS,
    Demonstration,
    Skill,
    SkillModel,
    check_person_params,
)

if TYPE_CHECKING:
    from ias_gym.skills.db_sqlite import _ErrorTranslation, _Transaction

#: An unknown id's error lists the ids there are up to this many (else their range).
MAX_LISTED_IDS = 20

#: Columns of ``skills`` that make up a :class:`SkillSummary` (in its field order), without
#: the last, ``person_params`` (:meth:`SkillQueries._summary_columns`).
_SUMMARY_COLUMNS = (
    "id, name, task, source, person_id, created, package_version, seed, env_kwargs, "
    "is_success, episode_return, length, duration"
)


@dataclass(frozen=True)
class SkillSummary:
    """A skill's row without its arrays (what :meth:`SkillDB.list_skills` returns).

    The fields not listed here are those of :class:`Skill`.

    Attributes:
        episode_return: undiscounted return of the demonstration.
        length: number of steps.
        duration: time spanned by the skill model [s].
    """

    id: int
    name: str
    task: str
    source: str
    person_id: str | None
    created: str
    package_version: str
    seed: int | None
    env_kwargs: dict[str, Any]
    is_success: bool
    episode_return: float
    length: int
    duration: float
    person_params: dict[str, float] | None = None

    @classmethod
    def _from_row(cls, row: tuple[Any, ...], path: Path) -> SkillSummary:
        (id_, name, task, source, person, created, version, seed, kwargs) = row[:9]
        success, ret, length, duration, params = row[9:14]
        try:
            env_kwargs = json.loads(kwargs)
            if not isinstance(env_kwargs, dict):
                raise TypeError(f"a {type(env_kwargs).__name__}, not an object")
            # JSON of plain numbers: parsing it runs no code
            person_params = None if params is None else check_person_params(json.loads(params))
            return cls(
                id=int(id_),
                name=name,
                task=task,
                source=source,
                person_id=person,
                created=created,
                package_version=version,
                seed=seed,
                env_kwargs=env_kwargs,
                is_success=bool(success),
                episode_return=float(ret),
                length=int(length),
                duration=float(duration),
                person_params=person_params,
            )
        except (TypeError, ValueError) as exc:  # a damaged row: one error type, its id
            raise SkillDBError(
                f"skill {id_} in {path} is corrupt: its row does not parse ({exc}); restore "
                f"a backup, or delete the skill with `ias-gym skills delete --db {path} "
                f"--id {id_}`"
            ) from None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict of every field (``return`` is the key of ``episode_return``)."""
        out = dataclasses.asdict(self)
        out["return"] = out.pop("episode_return")
        return out


class SkillQueries:
    """The read methods of :class:`~ias_gym.skills.db.SkillDB` (a mixin; see there)."""

    # Provided by SkillDB (declared here for the type checker).
    path: Path
    readonly: bool
    _checksums: bool
    _person_params: bool

    if TYPE_CHECKING:

        @property
        def conn(self) -> sqlite3.Connection: ...

        @property
        def schema_version(self) -> int: ...

        def _errors(self, action: str) -> _ErrorTranslation: ...

        def _transaction(self, mode: str = "IMMEDIATE") -> _Transaction: ...

    # ------------------------------------------------------------------ reads
    def _summary_columns(self) -> str:
        """The :class:`SkillSummary` columns (``NULL`` for a file before ``person_params``)."""
        person = "person_params" if self._person_params else "NULL"
        return f"{_SUMMARY_COLUMNS}, {person}"

    def _check_writable(self) -> None:
        if self.readonly:
            raise SkillDBError(f"skill database {self.path} is open read-only; open it with "
                               "SkillDB(path) to write")  # fmt: skip

    def _not_found(self, skill_id: int) -> SkillNotFoundError:
        ids = [int(r[0]) for r in self.conn.execute("SELECT id FROM skills ORDER BY id")]
        if not ids:
            have = "it holds no skills"
        elif len(ids) <= MAX_LISTED_IDS:
            have = f"its ids are {', '.join(map(str, ids))}"
        else:
            have = f"it holds {len(ids)} skills with ids {ids[0]}-{ids[-1]}"
        return SkillNotFoundError(f"no skill with id {skill_id} in {self.path}; {have}")

    def list_skills(
        self, task: str | None = None, success: bool | None = None
    ) -> list[SkillSummary]:
        """The stored skills, by id.

        Args:
            task: only skills of this env id.
            success: only successful (``True``) or failed (``False``) ones; ``None``: all.
        """
        query = f"SELECT {self._summary_columns()} FROM skills"
        where, params = _filters(task, success)
        with self._errors("read"):
            rows = self.conn.execute(f"{query}{where} ORDER BY id", params).fetchall()
        return [SkillSummary._from_row(r, self.path) for r in rows]

    def ids(self) -> list[int]:
        """The stored skills' ids, ascending (reads no other column: works on damaged rows)."""
        with self._errors("read"):
            return [int(r[0]) for r in self.conn.execute("SELECT id FROM skills ORDER BY id")]

    def tasks(self) -> list[str]:
        """The distinct task ids, sorted."""
        with self._errors("read"):
            return [r[0] for r in self.conn.execute("SELECT DISTINCT task FROM skills ORDER BY 1")]

    def __len__(self) -> int:
        with self._errors("read"):
            return int(self.conn.execute("SELECT count(*) FROM skills").fetchone()[0])

    def summary(self, skill_id: int) -> SkillSummary:
        """One skill's row without its arrays.

        Raises:
            SkillNotFoundError: no skill has this id.
        """
        with self._errors("read"):
            row = self.conn.execute(
                f"SELECT {self._summary_columns()} FROM skills WHERE id = ?", (int(skill_id),)
            ).fetchone()
            if row is None:
                raise self._not_found(skill_id)
        return SkillSummary._from_row(row, self.path)

    def get(self, skill_id: int) -> Skill:
        """Load a skill with its demonstration and model (arrays bit-identical, dtypes kept).

        Every array's checksum is verified before it is used.

        Raises:
            SkillNotFoundError: no skill has this id.
            SkillDBError: the stored arrays are incomplete, inconsistent or do not match
                their checksums (the message names the skill and the array), or the file
                predates checksums and was opened read-only (the message says how to
                migrate it).
        """
        checksum = "checksum" if self._checksums else "NULL"
        with self._errors("read"), self._transaction("DEFERRED"):  # one consistent snapshot
            row = self.conn.execute(
                f"SELECT {self._summary_columns()} FROM skills WHERE id = ?", (int(skill_id),)
            ).fetchone()
            if row is None:
                raise self._not_found(skill_id)
            arrays = self.conn.execute(
                f"SELECT part, name, dtype, shape, data, {checksum} FROM arrays WHERE skill_id = ?",
                (int(skill_id),),
            ).fetchall()
        summary = SkillSummary._from_row(row, self.path)
        parts: dict[str, dict[str, NDArray[Any]]] = {"demo": {}, "info": {}, "model": {}}
        for part, name, dtype, shape, data, digest in arrays:
            what = f"{part}/{name}"
            self._verify(skill_id, what, dtype, shape, data, digest)
            parts[part][name] = _decode(self.path, skill_id, what, dtype, shape, data)
        for part, names in (("demo", DEMO_ARRAYS), ("model", MODEL_ARRAYS)):
            missing = sorted(set(names) - set(parts[part]))
            if missing:
                raise SkillDBError(
                    f"skill {skill_id} in {self.path} is incomplete (missing {part} arrays "
                    f"{missing}); {self._delete_hint(skill_id)}"
                )
        skill = Skill(
            name=summary.name,
            task=summary.task,
            source=summary.source,
            demonstration=Demonstration(**parts["demo"], infos=parts["info"]),
            model=SkillModel(**parts["model"]),
            is_success=summary.is_success,
            seed=summary.seed,
            person_id=summary.person_id,
            env_kwargs=summary.env_kwargs,
            person_params=summary.person_params,
            id=summary.id,
            created=summary.created,
            package_version=summary.package_version,
        )
        if skill.length != summary.length:
            raise SkillDBError(
                f"skill {skill_id} in {self.path} is inconsistent: {skill.length} actions "
                f"stored, {summary.length} recorded; {self._delete_hint(skill_id)}"
            )
        return skill

    def _delete_hint(self, skill_id: int) -> str:
        return (
            f"restore a backup, or delete the skill with `ias-gym skills delete --db "
            f"{self.path} --id {skill_id}`"
        )

    def _verify(
        self, skill_id: int, what: str, dtype: str, shape: str, data: bytes, digest: str | None
    ) -> None:
        """Raise SkillDBError unless the array's bytes match its stored checksum."""
        if digest is None:
            if not self._checksums:
                raise SkillDBError(
                    f"{self.path} has schema version {self.schema_version}, written before "
                    "arrays had checksums, and was opened read-only; add them once with "
                    f"`ias-gym skills migrate --db {self.path}` (any open for writing does)"
                )
            raise SkillDBError(
                f"skill {skill_id} in {self.path} is corrupt: array {what} has no checksum; "
                f"{self._delete_hint(skill_id)}"
            )
        try:
            actual = array_checksum(dtype, shape, data)
        except (AttributeError, TypeError):  # not text / bytes: a damaged row
            actual = None
        if actual != digest:
            raise SkillDBError(
                f"skill {skill_id} in {self.path} is corrupt: array {what} does not match its "
                f"checksum (its stored bytes changed since it was written); "
                f"{self._delete_hint(skill_id)}"
            )

    def check_skill(self, skill_id: int) -> None:
        """Verify one skill completely without returning it: every array against its
        checksum, complete and consistent (:meth:`get`), its first-observation copy (the
        nearest-state index) against its checksum and the demonstration, and the skill's
        fields (:meth:`Skill.validate`).

        Raises:
            SkillNotFoundError: no skill has this id.
            SkillDBError: the first problem found (naming the skill and the array).
        """
        skill = self.get(skill_id)
        checksum = "initial_observation_checksum" if self._checksums else "NULL"
        with self._errors("read"):
            first, digest = self.conn.execute(
                f"SELECT initial_observation, {checksum} FROM skills WHERE id = ?",
                (int(skill_id),),
            ).fetchone()
        shape = json.dumps([len(first) // 8])
        self._verify(skill_id, "initial_observation", "<f8", shape, first, digest)
        expected = np.ascontiguousarray(skill.demonstration.observations[0], dtype="<f8")
        if first != expected.ravel().tobytes():
            raise SkillDBError(
                f"skill {skill_id} in {self.path} is inconsistent: initial_observation differs "
                f"from the first stored observation; {self._delete_hint(skill_id)}"
            )
        try:
            skill.validate()
        except ValueError as exc:
            raise SkillDBError(
                f"skill {skill_id} in {self.path} is invalid: {exc}; {self._delete_hint(skill_id)}"
            ) from None

    def nearest_initial_state(
        self, observation: Any, task: str | None = None, k: int = 1
    ) -> list[tuple[SkillSummary, float]]:
        """The skills whose demonstration starts closest to ``observation``.

        Distance is Euclidean between ``observation`` and each demonstration's first
        observation (flattened); skills whose observations have another size are skipped.

        Args:
            observation: an observation of the task's env.
            task: only skills of this env id.
            k: how many to return.

        Returns:
            Up to ``k`` pairs ``(summary, distance)``, nearest first; empty if none match.

        Raises:
            ValueError: ``observation`` is not finite, or ``k < 1``.
            SkillDBError: a candidate's stored first observation does not match its
                checksum (naming the skill).
        """
        obs = np.asarray(observation, dtype=np.float64).ravel()
        if not np.all(np.isfinite(obs)):
            raise ValueError("observation contains NaN or inf")
        if k < 1:
            raise ValueError(f"k must be >= 1, got {k}")
        where, params = _filters(task, None)
        where += (" AND " if where else " WHERE ") + "observation_dim = ?"
        checksum = "initial_observation_checksum" if self._checksums else "NULL"
        with self._errors("read"):
            rows = self.conn.execute(
                f"SELECT {self._summary_columns()}, initial_observation, {checksum} FROM skills"
                f"{where} ORDER BY id",
                (*params, obs.size),
            ).fetchall()
        if not rows:
            return []
        shape = json.dumps([obs.size])
        for r in rows:
            self._verify(int(r[0]), "initial_observation", "<f8", shape, r[-2], r[-1])
        starts = np.stack([np.frombuffer(r[-2], dtype="<f8") for r in rows])
        distance = np.linalg.norm(starts - obs, axis=1)
        order = np.argsort(distance, kind="stable")[:k]
        return [
            (SkillSummary._from_row(rows[i][:-2], self.path), float(distance[i])) for i in order
        ]

    def integrity_check(self) -> None:
        """Run SQLite's full ``PRAGMA integrity_check``.

        Raises:
            SkillDBError: the file is damaged (the message has SQLite's findings).
        """
        with self._errors("check"):
            result = [r[0] for r in self.conn.execute("PRAGMA integrity_check")]
        if result != ["ok"]:
            raise SkillDBError(
                f"{self.path} is corrupt ({'; '.join(result[:5])}); restore it from a backup "
                "or delete it"
            )


def _filters(task: str | None, success: bool | None) -> tuple[str, tuple[Any, ...]]:
    clauses: list[str] = []
    params: list[Any] = []
    if task is not None:
        clauses.append("task = ?")
        params.append(task)
    if success is not None:
        clauses.append("is_success = ?")
        params.append(int(success))
    return ((" WHERE " + " AND ".join(clauses)) if clauses else ""), tuple(params)

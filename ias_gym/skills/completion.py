"""Do the simulated persons complete the glove skills? One session per (person, skill).

:func:`glove_session` runs one unassisted session of ``IAS-GloveGrasp-v0`` (zero action: the
person alone) and says how it ended (:class:`SessionOutcome`: success, and why not);
:func:`completion` runs it over persons x skills on a :mod:`ias_gym.runtime.jobs` backend and
:func:`completion_table` reports the rate per skill with its 95 % Wilson interval
(:mod:`ias_gym.rates`). ``train/completion_table.py`` is the command behind the table in
``docs/population.md``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from ias_gym.errors import PersonCannotError
from ias_gym.glove.hand import PersonParams
from ias_gym.glove.profile_cache import default_calibration
from ias_gym.glove.skills import SKILLS, check_skill, person_parameters
from ias_gym.rates import Rate
from ias_gym.rollout import FunctionPolicy, rollout
from ias_gym.runtime.jobs import SERIAL, Backend, run_jobs
from ias_gym.sim.glove_scene import load_glove_scene

#: Why a session failed (``SessionOutcome.reason``).
REASONS: tuple[str, ...] = ("", "dropped", "not lifted", "not placed", "person")


@dataclass(frozen=True)
class SessionOutcome:
    """How one unassisted glove session ended.

    Attributes:
        person_id, skill, operator: what ran.
        success: the env's ``is_success`` at the last step.
        reason: ``""`` on success, else ``"dropped"`` (the pen fell: terminated),
            ``"not lifted"`` (never ``lift_height`` above its start), ``"not placed"``
            (``lift_place``: lifted, but not put back) or ``"person"`` (the
            person's side: see ``detail``).
        detail: the env's ``operator_failure`` (why the person could not), or ``""``.
        pen_height_m: the pen's height above its start at the end [m].
        params: the person's drawn parameters (hand and style), by name.
    """

    person_id: str
    skill: str
    operator: str
    success: bool
    reason: str
    detail: str
    pen_height_m: float
    params: dict[str, float]


def glove_session(
    person_id: str, skill: str, operator: str = "closed_loop", seed: int = 0
) -> SessionOutcome:
    """One unassisted session of ``skill`` by ``person_id`` (zero action).

    Raises:
        InputError: an unknown skill or operator, an invalid person id.
    """
    check_skill(skill)
    try:
        env = gym.make("IAS-GloveGrasp-v0", person_id=person_id, skill=skill, operator=operator)
    except PersonCannotError as exc:
        params = person_parameters(person_id)
        return SessionOutcome(person_id, skill, operator, False, "person", str(exc), 0.0, params)
    try:
        zero = np.zeros(env.action_space.shape or (), dtype=np.float32)
        trajectory = rollout(
            env, FunctionPolicy(lambda _obs: zero), seed, keep_observations=False, keep_infos=True
        )
        lift_height = float(env.unwrapped.config.lift_height)  # type: ignore[attr-defined]
    finally:
        env.close()
    info, terminated = trajectory.final_info, trajectory.terminated
    infos = trajectory.infos or (info,)
    lifted = max(float(i.get("pen_height", -np.inf)) for i in infos) >= lift_height
    success = bool(info["is_success"])
    detail = str(info.get("operator_failure", ""))
    reason = failure_reason(skill, success, terminated, detail, lifted)
    return SessionOutcome(
        person_id=person_id,
        skill=skill,
        operator=operator,
        success=success,
        reason=reason,
        detail=detail,
        pen_height_m=float(info["pen_height"]),
        params=person_parameters(person_id),
    )


def failure_reason(skill: str, success: bool, dropped: bool, detail: str, lifted: bool) -> str:
    """Why a session failed (one of :data:`REASONS`; ``""``: it did not).

    Args:
        skill: the session's skill.
        success: the env's ``is_success`` at the end.
        dropped: the episode terminated (the pen fell).
        detail: the env's ``operator_failure`` (the person's side), or ``""``.
        lifted: the pen was ``lift_height`` above its start at some step.
    """
    if success:
        return ""
    if dropped:
        return "dropped"
    if detail:
        return "person"
    return "not placed" if skill == "lift_place" and lifted else "not lifted"


def _calibrate(person_id: str) -> None:
    """Train (or load) the cached glove calibration of ``person_id`` (the env of a person
    who cannot pinch the pen is never built, nor is their calibration needed)."""
    person = PersonParams.sample(person_id)
    try:
        load_glove_scene(person)
    except PersonCannotError:
        return
    default_calibration(person, progress=False)


@dataclass(frozen=True)
class _SessionJob:
    """A picklable job: ``(person_id, skill) -> SessionOutcome``."""

    operator: str
    seed: int

    def __call__(self, item: tuple[str, str]) -> SessionOutcome:
        return glove_session(item[0], item[1], self.operator, self.seed)


def completion(
    person_ids: Sequence[str],
    skills: Sequence[str] = SKILLS,
    operator: str = "closed_loop",
    *,
    seed: int = 0,
    backend: Backend = SERIAL,
    progress: bool = False,
) -> list[SessionOutcome]:
    """Every person's session of every skill, in (person, skill) order.

    Each new person's glove calibration is trained first, one person per worker, so that no
    two workers train the same one.
    """
    run_jobs(_calibrate, list(person_ids), backend, desc="calibrations", progress=progress)
    items = [(p, s) for p in person_ids for s in skills]
    return run_jobs(
        _SessionJob(operator, seed), items, backend, desc=f"{operator} sessions", progress=progress
    )


def completion_table(outcomes: Sequence[SessionOutcome]) -> dict[str, dict[str, Any]]:
    """Per skill (and ``"all"``): the success rate with its Wilson interval and the count of
    each failure reason."""
    rows: dict[str, dict[str, Any]] = {}
    groups: dict[str, list[SessionOutcome]] = {}
    for o in outcomes:
        groups.setdefault(o.skill, []).append(o)
    groups["all"] = list(outcomes)
    for skill, group in groups.items():
        reasons = {r: sum(o.reason == r for o in group) for r in REASONS if r}
        rows[skill] = {**Rate.of([o.success for o in group]).to_dict(), "failures": reasons}
    return rows

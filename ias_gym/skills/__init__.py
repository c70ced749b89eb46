"""The skill database: skills of paper sec. 3 (Proposition 1) with their demonstrations.

- :class:`SkillDB` stores :class:`Skill` objects (a :class:`SkillModel` - contact schedule,
  object trajectory, internal forces of G(t) - a :class:`Demonstration` and provenance) in
  one SQLite file, one transaction per write, no pickle.
- :func:`record_skills` rolls out a policy on a pen task, or records glove sessions of
  ``IAS-GloveGrasp-v0`` (policy ``teleop``), and stores every episode.
- :func:`export_minari` writes the demonstrations of a task as a Minari dataset (no jax).
- :func:`check_database` verifies every skill's checksums.

The ``ias-gym skills ...`` commands live in :mod:`ias_gym.cli.skills_commands` (this package never
imports the command line).
"""

from ias_gym.baselines.policies import policy_source
from ias_gym.skills.check import check_database
from ias_gym.skills.db import (
    SCHEMA_VERSION,
    SkillDB,
    SkillDBError,
    SkillNotFoundError,
    SkillSummary,
    array_checksum,
)
from ias_gym.skills.glove_session import (
    GloveSkillModelRecorder,
    glove_session_source,
)
from ias_gym.skills.minari_export import export_minari
from ias_gym.skills.record import (
    SkillModelRecorder,
    SkillSampler,
    record_episode,
    record_skills,
    skill_model_recorder,
    stack_infos,
)
from ias_gym.skills.skill import Demonstration, Skill, SkillModel

__all__ = [
    "SCHEMA_VERSION",
    "Demonstration",
    "GloveSkillModelRecorder",
    "Skill",
    "SkillDB",
    "SkillDBError",
    "SkillModel",
    "SkillModelRecorder",
    "SkillNotFoundError",
    "SkillSampler",
    "SkillSummary",
    "array_checksum",
    "check_database",
    "export_minari",
    "glove_session_source",
    "policy_source",
    "record_episode",
    "record_skills",
    "skill_model_recorder",
    "stack_infos",
]

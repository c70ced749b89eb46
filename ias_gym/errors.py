"""One base class for the errors ``ias_gym`` raises on purpose.

Every error the package raises for a reason a user can act on (bad input, a file that is not
what it should be, a grasp the solver cannot hold, a glove that does not answer) derives from
:class:`IasGymError`, so the ``ias-gym`` command can catch them as one type and print one
line. Each keeps its historical built-in base too (``ValueError``, ``KeyError``, ...), so code
that caught those still works. They are all defined here, in one place; the modules that
raise them import them from here (and still export them under their old names).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any


class IasGymError(Exception):
    """Base class of the package's own errors; the message says what is wrong and what to do."""


class InputError(IasGymError, ValueError):
    """An argument, a file or a setting given by the user cannot be used (the message names it)."""


class PersonCannotError(InputError):
    """A simulated person physically cannot do what was asked (e.g. no pen pinch is within
    their hand's reach and range of motion); the message says which person and why."""


class PolicyNotFoundError(InputError, FileNotFoundError):
    """A policy spec that is neither a known name nor an existing file."""


class MissingFileError(InputError, FileNotFoundError):
    """A file the user named (a database, a dataset) does not exist."""


class MissingDependencyError(IasGymError, ImportError):
    """An optional dependency is not installed (the message says which extra to install)."""


class WorkerError(IasGymError):
    """A worker process died, timed out or could not start.

    Raised by the vector envs' pool (:class:`~ias_gym.runtime.workers.BatchedWorkers`) and by
    the job runner (:func:`~ias_gym.runtime.jobs.run_jobs`), which raises it after every other
    job is done, naming the jobs whose worker died on every attempt.

    Attributes:
        items: the failed jobs' items (seeds), in order (empty for a vector env's worker).
    """

    def __init__(self, message: str, items: Sequence[Any] = ()) -> None:
        super().__init__(message)
        self.items = list(items)

    def __reduce__(self) -> tuple[Any, ...]:  # picklable with its items
        return (type(self), (str(self), self.items))


class UnknownEnvError(InputError, LookupError):
    """An env id that gymnasium does not know (the message lists the ``IAS-*`` ids)."""


class ProfileError(IasGymError, ValueError):
    """A profile file that cannot be used; the message says why and what to do."""


class GraspRankError(IasGymError, ValueError):
    """Raised when W does not have full row rank 6 (the paper assumes rank W = 6)."""


class InfeasibleGraspError(IasGymError, ValueError):
    """No wrench intensities satisfy equilibrium, the normal-force bound and the cones."""


class GloveTimeoutError(IasGymError, RuntimeError):
    """No sensor sample arrived in time (glove off, wrong channel or bit rate?)."""


class ProtocolError(IasGymError, ValueError):
    """A frame that does not fit the protocol (unknown id, wrong length, value out of range)."""


class UnknownIdError(ProtocolError):
    """A frame whose id is not in the protocol: another node's traffic, not a fault."""


class ReplayError(InputError):
    """The file is not a recorded glove session: missing, not a python-can log of a supported
    format, empty or truncated, no host cycles, or a cycle without its sample."""


class OutputExistsError(InputError, FileExistsError):
    """An output file exists and replacing it was not asked for (``--overwrite``)."""


class RayMissingError(IasGymError):
    """``--ray`` was asked for but Ray (the ``[distributed]`` extra) is not installed."""


class RolloutError(IasGymError, ValueError):
    """A policy gave :func:`~ias_gym.rollout.rollout` something the env cannot take (the
    message says what)."""


class PolicyFileError(InputError):
    """A policy file cannot be used (not an SB3 model, corrupt, or for another env)."""


class UntrustedPickleError(PolicyFileError):
    """A field that acting needs is stored only as a pickle (see
    :data:`~ias_gym.safe_sb3.TRUST_HINT`)."""


class NameNotFoundError(IasGymError, KeyError):
    """A name that the model does not contain; the message lists the names it does."""

    def __str__(self) -> str:
        return str(self.args[0])


class SkillDBError(IasGymError):
    """The skill database cannot be used: not a skill database, corrupt, newer, or locked."""


class SkillNotFoundError(SkillDBError):
    """No skill with the requested id."""


class OfflineDatasetError(InputError):
    """A dataset for offline RL that cannot be used: missing, empty, of another env, or of
    other observation or action shapes than the env's (the message names the dataset)."""


class SkillTransferError(InputError):
    """A stored skill cannot be transferred (no contacts, too short, ...); says which."""

"""One base class for the errors ``ias_gym`` raises on purpose.

Every error the package raises for a reason a user can act on (bad input, a file that is not
what it should be, a grasp the solver cannot hold, a glove that does not answer) derives from
:class:`IasGymError`, so the ``ias-gym`` command can catch them as one type and print one
line. Each keeps its historical built-in base too (``ValueError``, ``KeyError``, ...), so code
that caught those still works.
"""

from __future__ import annotations


class IasGymError(Exception):
    """Base class of the package's own errors; the message says what is wrong and what to do."""


class InputError(IasGymError, ValueError):
    """An argument, a file or a setting given by the user cannot be used (the message names it)."""


class PersonCannotError(InputError):
    """A simulated person physically cannot do what was asked (e.g. no pen pinch is within
    their hand's reach and range of motion); the message says which person and why."""

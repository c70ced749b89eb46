"""Output files: checked before any work starts, written atomically, never replaced silently.

A command that renders a video or computes a figure for a minute must not fail only when it
writes the result, and must not replace a file the user did not ask it to replace. So the
commands call :func:`check_output_file` / :func:`prepare_output_dir` first (they try to
create a file where the output will go: ``os.access`` says yes to root even on ``/proc``),
and write through :func:`atomic_output` (a temporary file in the same directory, renamed
into place only when complete, so a reader never sees half a file).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path

from ias_gym.errors import (
    InputError,
    OutputExistsError,
)


def _refuse_existing(paths: Sequence[Path]) -> None:
    if paths:
        names = ", ".join(str(p) for p in paths)
        raise OutputExistsError(
            f"{names} already exist{'s' if len(paths) == 1 else ''}; pass --overwrite "
            "(overwrite=True) to replace, or choose another path"
        )


def _probe_writable(directory: Path, what: str) -> None:
    """Create and remove a file in ``directory``: the only check that is true for root too."""
    try:
        fd, tmp = tempfile.mkstemp(dir=directory, prefix=".ias-gym-probe.")
    except OSError as exc:
        raise InputError(
            f"{what}: cannot write into {directory} ({exc.strerror or exc}); choose another "
            "directory"
        ) from None
    os.close(fd)
    os.unlink(tmp)


def check_output_file(
    path: Path | str,
    *,
    overwrite: bool = False,
    suffixes: Iterable[str] = (),
    what: str = "output file",
) -> Path:
    """Check, before any work, that ``path`` can be written as a new (or replaced) file.

    Args:
        path: the file to be written.
        overwrite: allow replacing an existing file.
        suffixes: if given, the allowed file name suffixes (lower case, with the dot).
        what: what the file is, for the messages (e.g. ``"--video"``).

    Returns:
        ``path`` as a :class:`~pathlib.Path`.

    Raises:
        InputError: wrong suffix, ``path`` is a directory, its directory does not exist or
            cannot be written.
        OutputExistsError: ``path`` exists and ``overwrite`` is false.
    """
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{what} {path} is a directory; give a file name")
    allowed = tuple(suffixes)
    if allowed and path.suffix.lower() not in allowed:
        raise InputError(f"{what} {path} must end with {' or '.join(allowed)}")
    if path.exists() and not overwrite:
        _refuse_existing([path])
    parent = path.parent
    if not parent.is_dir():
        raise InputError(f"{what} {path}: the directory {parent} does not exist; create it first")
    _probe_writable(parent, f"{what} {path}")
    return path


def check_output_files(
    outputs: Mapping[str, Path | str | None], *, overwrite: bool = False
) -> dict[str, Path | None]:
    """:func:`check_output_file` for each of a command's output files, keyed by what names
    them (``{"--out": ..., "--report": ...}``); an output not asked for (None) stays None.

    Raises:
        InputError: as :func:`check_output_file`, or two of them are one file.
        OutputExistsError: as :func:`check_output_file`.
    """
    checked: dict[str, Path | None] = {}
    for what, path in outputs.items():
        checked[what] = (
            None if path is None else check_output_file(path, overwrite=overwrite, what=what)
        )
    given = [(what, p.resolve()) for what, p in checked.items() if p is not None]
    for i, (what, path) in enumerate(given):
        for other, other_path in given[:i]:
            if path == other_path:
                raise InputError(f"{what}: give a file other than {other}'s")
    return checked


def prepare_output_dir(
    directory: Path | str, names: Iterable[str], *, overwrite: bool = False
) -> Path:
    """Create ``directory`` if missing and check, before any work, that ``names`` can be
    written into it.

    Args:
        directory: the output directory (created with its parents if missing).
        names: the file names the command will write there.
        overwrite: allow replacing existing files of those names.

    Returns:
        ``directory`` as a :class:`~pathlib.Path`.

    Raises:
        InputError: the directory cannot be created or written, or one of the names is a
            directory.
        OutputExistsError: some of the files exist and ``overwrite`` is false (all are named).
    """
    directory = Path(directory)
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise InputError(f"output directory {directory} is a file; give a directory") from None
    except OSError as exc:
        raise InputError(
            f"cannot create the output directory {directory}: {exc.strerror or exc}"
        ) from None
    _probe_writable(directory, f"output directory {directory}")
    targets = [directory / name for name in names]
    for target in targets:
        if target.is_dir():
            raise InputError(f"{target} is a directory; it would be an output file")
    if not overwrite:
        _refuse_existing([t for t in targets if t.exists()])
    return directory


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def atomic_output(path: Path | str, *, overwrite: bool = False) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; when the block ends without an error, move the
    file written there to ``path``, else remove it.

    The temporary file has ``path``'s suffix (writers such as ffmpeg pick the format by
    it). Without ``overwrite`` the move is a hard link, which fails if ``path`` appeared
    in the meantime, so an existing file is never replaced.

    Args:
        path: the final file.
        overwrite: allow replacing an existing ``path``.

    Raises:
        OutputExistsError: ``path`` exists at the end and ``overwrite`` is false.
        OSError: the directory cannot be written.
    """
    path = Path(path)
    fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=path.suffix)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; outputs are not secret
        if overwrite:
            os.replace(tmp, path)
        else:
            try:
                os.link(tmp, path)
            except FileExistsError:
                _refuse_existing([path])
            except OSError:  # a file system without hard links: check, then rename
                if path.exists():
                    _refuse_existing([path])
                os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)

"""Files a user points the kit at (``dgt costmap --out``, ``dgt plan``'s figures), checked
before any work: one line (a :class:`OutputPathError`, exit status 2) instead of a
traceback after an hour of collection and training (docs/reliability.md).

:func:`check_output_path`: the target's directory exists or can be made and takes a file,
the target is no directory, its name fits the file system's ``NAME_MAX`` and ``PATH_MAX``
with the kit's lock and temporary files beside it, and it is none of the command's inputs.
:func:`bounded_name`: a name derived from user input (a vehicle's name, a DEM file's stem)
cut to a length every file name built on it can hold.
"""

from __future__ import annotations

import errno
import hashlib
import os
import tempfile
from collections.abc import Iterable
from pathlib import Path

BESIDE_BYTES = len("..lock")
"""Bytes the kit adds to a target's name for the files beside it: ``.<name>.lock`` (the
writers' lock, :func:`dgt_lib.core.artifacts.build_lock`); the temporary file's name is
cut to fit (:func:`dgt_lib.core.artifacts._atomic_write`)."""

NAME_PART_CHARS = 48
"""Characters a name taken from user input keeps in a file name (:func:`bounded_name`):
a plan's file name joins a world's and a vehicle's name with about 60 characters of
coordinates and hashes, well inside the 255 bytes most file systems allow."""


class OutputPathError(ValueError):
    """An output path that cannot be written (the message names it and says why)."""


def bounded_name(text: str, limit: int = NAME_PART_CHARS) -> str:
    """``text`` when it has at most ``limit`` characters, else its first characters, ``~``
    and 8 hex digits of its SHA-256, ``limit`` in all: two long names that share their
    start stay distinct. Path separators become ``_``."""
    text = text.replace(os.sep, "_").replace("\0", "_")
    if len(text) <= limit:
        return text
    digest = hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest()[:8]
    return f"{text[:limit - 9]}~{digest}"


def _limit(directory: Path, name: str, default: int) -> int:
    try:
        return os.pathconf(directory, name)
    except (OSError, ValueError):
        return default


def _writable_directory(directory: Path, what: str) -> None:
    """Make ``directory`` when missing and try a file in it; :class:`OutputPathError` when
    it cannot take one."""
    if directory.exists() and not directory.is_dir():
        raise OutputPathError(f"{what}: {directory} is not a directory")
    try:
        directory.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=directory, prefix=".dgt-", suffix=".probe")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        why = exc.strerror or str(exc)
        raise OutputPathError(f"{what}: cannot write in {directory} ({why})") from None


def check_output_path(path: str | Path, *, what: str = "--out",
                      inputs: Iterable[str | Path] = ()) -> Path:
    """``path`` made absolute, once it is known to be writable here (module docstring);
    :class:`OutputPathError` naming ``what`` otherwise. An existing file is fine (it is
    replaced whole); an input of the command (``inputs``: the world's file) is not, by its
    resolved path (a link or ``./`` does not hide it). Makes the directory when missing."""
    if str(path).strip() == "":
        raise OutputPathError(f"{what} is empty: give a file name")
    target = Path(os.path.abspath(Path(path).expanduser()))
    name_max = _limit(target.parent if target.parent.is_dir() else Path("/"),
                      "PC_NAME_MAX", 255)
    if len(os.fsencode(target.name)) + BESIDE_BYTES > name_max:
        raise OutputPathError(f"{what}: the file name {target.name[:40]}… has "
                              f"{len(os.fsencode(target.name))} bytes; at most "
                              f"{name_max - BESIDE_BYTES} fit here")
    if target.is_dir():
        raise OutputPathError(f"{what} {target} is a directory: give a file name")
    path_max = _limit(Path("/"), "PC_PATH_MAX", 4096)
    if len(os.fsencode(str(target))) + BESIDE_BYTES >= path_max:
        raise OutputPathError(f"{what}: the path {str(target)[:40]}… is longer than the "
                              f"{path_max} bytes a path may have here")
    for given in inputs:
        if _same_file(target, Path(given)):
            raise OutputPathError(f"{what} {target} is also an input of this command: "
                                  "writing it would destroy the input; choose another file")
    _writable_directory(target.parent, what)
    return target


def _same_file(a: Path, b: Path) -> bool:
    """Whether two paths name one file (resolved; a hard link by its inode)."""
    try:
        if a.resolve() == b.resolve():
            return True
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError as exc:
        if exc.errno in (errno.ENAMETOOLONG, errno.ELOOP):
            return False
        raise

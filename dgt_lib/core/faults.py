"""Faults from outside the kit said in one line (docs/reliability.md): a data directory
that cannot be made, is not a directory, is read-only or full, and a cluster that gave up
on a job after its workers kept dying. ``dgt`` prints the line, what it kept, and exits 1
instead of showing a traceback. SIGTERM stops a command as Ctrl-C does
(:func:`sigterm_as_interrupt`), with the exit status a shell expects (143).
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import signal
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

STORAGE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES,
                            errno.EPERM})
"""The ``OSError`` numbers of a directory that cannot take a file: no space (or quota),
a read-only file system, no permission."""

DATA_DIR_HINT = "set DGT_DATA_DIR to a directory you can write"


class SetupError(RuntimeError):
    """What this machine lacks to run a command, found before any work (the message says
    what and how to fix it)."""


class DataDirError(SetupError):
    """A data directory that cannot be used at all: not a directory, or not creatable."""


def is_storage_error(exc: BaseException) -> bool:
    """Whether ``exc`` is an ``OSError`` of :data:`STORAGE_ERRNOS`."""
    return isinstance(exc, OSError) and exc.errno in STORAGE_ERRNOS


def prepare_data_dir(root: Path) -> None:
    """Make ``root`` (``$DGT_DATA_DIR`` or ``data/``) when it is missing, before any work;
    :class:`DataDirError` when it is not a directory or cannot be made. Whether it can be
    written is not asked here: a fully cached run writes nothing, and an artifact to build
    checks its own directory before it is built (``artifacts.ensure``)."""
    root = Path(root)
    source = "DGT_DATA_DIR" if os.environ.get("DGT_DATA_DIR") else "the default"
    where = f"the data directory {root} ({source})"
    if root.exists() and not root.is_dir():
        raise DataDirError(f"{where} is not a directory; {DATA_DIR_HINT}")
    if not root.exists():
        try:
            root.mkdir(parents=True)
        except FileExistsError:  # made meanwhile by a run beside this one
            pass
        except OSError as exc:
            raise DataDirError(f"cannot create {where}: {exc.strerror}; "
                               f"{DATA_DIR_HINT}") from None


def _size(n_bytes: float) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n_bytes < 1000 or unit == "GB":
            return f"{n_bytes:.0f} {unit}" if unit == "B" else f"{n_bytes:.1f} {unit}"
        n_bytes /= 1000
    raise AssertionError("unreachable")


def free_bytes(path: Path) -> int | None:
    """Free bytes on the file system of ``path`` (its nearest existing directory), or None."""
    path = Path(path)
    for candidate in (path, *path.parents):
        try:
            return shutil.disk_usage(candidate).free
        except OSError:
            continue
    return None


def storage_message(exc: OSError) -> str:
    """One line for an ``OSError`` of :data:`STORAGE_ERRNOS`: what could not be written,
    where, why, the free space and (``exc.needed_bytes``, set by ``artifacts.save``) how
    much the file needed, and what to do."""
    where = exc.filename or "a file of the data directory"
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        free = free_bytes(Path(where))
        need = getattr(exc, "needed_bytes", None)
        space = ("" if free is None else f"{_size(free)} free"
                 ) + ("" if need is None else f", about {_size(need)} needed")
        return (f"no space left to write {where}{f' ({space})' if space else ''}: free some "
                f"space, or {DATA_DIR_HINT} on a larger disk")
    why = "read-only file system" if exc.errno == errno.EROFS else "permission denied"
    return f"cannot write {where} ({why}): {DATA_DIR_HINT} (a fully cached run writes nothing)"


GAVE_UP = {
    "distributed.scheduler.KilledWorker": (
        "the Dask cluster gave up on a job after the workers running it died "
        "(distributed.scheduler.allowed-failures times): usually out of memory — give the "
        "workers more memory or run fewer per machine (--workers)"),
}
"""A cluster's "I give up on this job" exceptions (by module and class name, so
``distributed`` is not imported to recognise them) → what happened and what to do."""


def gave_up_message(exc: BaseException) -> str | None:
    """The sentence for a cluster that gave up on a job (:data:`GAVE_UP`), else None."""
    for cls in type(exc).__mro__:
        text = GAVE_UP.get(f"{cls.__module__}.{cls.__qualname__}")
        if text is not None:
            return text
    return None


def explain(exc: BaseException) -> str | None:
    """One line for a fault from outside the kit (a :class:`SetupError`,
    :func:`storage_message`, :func:`gave_up_message`), or None for any other exception."""
    if isinstance(exc, SetupError):
        return str(exc)
    if is_storage_error(exc):
        return storage_message(exc)
    return gave_up_message(exc)


@contextlib.contextmanager
def report_writes(what: str) -> Iterator[None]:
    """Around writing a report the cache does not need (tables, figures, recordings): a
    read-only or full disk is one line on stderr and the run goes on, so a fully cached run
    on a read-only data directory still succeeds; the stored results stand."""
    try:
        yield
    except OSError as exc:
        if not is_storage_error(exc):
            raise
        print(f"[dgt] {what} not written: {exc.strerror} ({exc.filename}); the cached "
              "results stand", file=sys.stderr)


class Terminated(KeyboardInterrupt):
    """SIGTERM (``kill``, a batch scheduler ending a job, a container stopping) raised as
    Ctrl-C is, so every path that stops on Ctrl-C — workers terminated, clusters stopped,
    finished work kept — stops on it too (:func:`sigterm_as_interrupt`)."""

    signum = signal.SIGTERM


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """While inside, SIGTERM raises :class:`Terminated` in the main thread instead of
    killing the process outright. Left alone where SIGTERM is ignored on purpose, or off
    the main thread (only it may set handlers). A process forked inside (a pool worker
    between its fork and its initializer) that gets SIGTERM dies of it, as by default."""
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGTERM) is signal.SIG_IGN:
        yield
        return

    owner = os.getpid()

    def raise_terminated(signum: int, frame: object) -> None:
        if os.getpid() != owner:  # a forked worker, hit before its initializer ran
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            os.kill(os.getpid(), signal.SIGTERM)  # dies as SIGTERM kills, no traceback
            return
        raise Terminated()

    previous = signal.signal(signal.SIGTERM, raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def interrupted_status(exc: KeyboardInterrupt) -> int:
    """The exit status after Ctrl-C or SIGTERM, as a shell reports a process the signal
    killed: 128 + the signal's number (130, 143)."""
    return 128 + int(getattr(exc, "signum", signal.SIGINT))

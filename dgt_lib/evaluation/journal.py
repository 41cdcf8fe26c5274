"""The trial journal: every finished trial appended to a file as soon as it ends, so an
experiment stopped by Ctrl-C or a crash resumes where it stopped.

The file is a sequence of pickled records. A record cut short by a crash (the last one)
is ignored when read back.
"""

from __future__ import annotations

import pickle
from collections.abc import Hashable
from pathlib import Path
from typing import Any


def read_journal(path: str | Path, key=lambda record: record.task) -> dict[Hashable, Any]:
    """The records in a journal file by ``key(record)`` (a later record of the same key
    wins); a missing file is empty."""
    done: dict[Hashable, Any] = {}
    path = Path(path)
    if not path.exists():
        return done
    with open(path, "rb") as f:
        while True:
            try:
                record = pickle.load(f)
            except (EOFError, pickle.UnpicklingError, AttributeError, ValueError):
                break  # end of file, or a half-written last record
            done[key(record)] = record
    return done


class Journal:
    """Append records to a journal file, each flushed at once (a context manager)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "ab")  # noqa: SIM115 - closed in close()

    def append(self, record: Any) -> None:
        pickle.dump(record, self._file)
        self._file.flush()

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> Journal:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

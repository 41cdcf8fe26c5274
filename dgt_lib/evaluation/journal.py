"""The trial journal: every finished trial appended to a file as soon as it ends, so an
experiment stopped by Ctrl-C or a crash resumes where it stopped.

Each record is framed: ``b"DGTJ"``, the payload's length and its CRC-32 (two
little-endian uint32), then the payload (a pickle) — written in one call. A damaged
record (cut short by a crash, or corrupted) is skipped when the file is read back, with
one warning; the records after it are still read, so only the damaged ones are redone.
Opening a damaged journal to append rewrites it without the damaged records first.
"""

from __future__ import annotations

import os
import pickle
import struct
import warnings
import zlib
from collections.abc import Hashable, Iterator
from pathlib import Path
from typing import Any

MAGIC = b"DGTJ"
_HEADER = struct.Struct("<4sII")  # magic, payload length [bytes], CRC-32 of the payload
DAMAGED = object()
"""What :func:`_scan` yields for a damaged stretch of a journal."""


def encode_record(record: Any) -> bytes:
    """One framed journal record: header (magic, length, CRC-32) + the pickled record."""
    payload = pickle.dumps(record, protocol=pickle.HIGHEST_PROTOCOL)
    return _HEADER.pack(MAGIC, len(payload), zlib.crc32(payload)) + payload


def _framed(data: bytes, pos: int) -> tuple[Any, int] | None:
    """The framed record at ``pos`` and the position after it; None if it is damaged
    (cut short, wrong checksum, or a payload that does not unpickle)."""
    if len(data) - pos < _HEADER.size:
        return None
    _, length, crc = _HEADER.unpack_from(data, pos)
    start, end = pos + _HEADER.size, pos + _HEADER.size + length
    if end > len(data) or zlib.crc32(data[start:end]) != crc:
        return None
    try:
        return pickle.loads(data[start:end]), end
    except Exception:  # noqa: BLE001 - any failure means a damaged record
        return None


def _scan(data: bytes) -> Iterator[Any]:
    """Every record of a journal's bytes in order, :data:`DAMAGED` for each damaged
    stretch (skipped up to the next frame's magic)."""
    pos = 0
    while pos < len(data):
        loaded = _framed(data, pos) if data.startswith(MAGIC, pos) else None
        if loaded is None:
            yield DAMAGED
            found = data.find(MAGIC, pos + 1)
            pos = found if found >= 0 else len(data)
        else:
            yield loaded[0]
            pos = loaded[1]


def read_journal(path: str | Path, key=lambda record: record.task) -> dict[Hashable, Any]:
    """The records in a journal file by ``key(record)`` (a later record of the same key
    wins); a missing file is empty. Damaged records are skipped with one warning that
    counts them; the valid records after them are kept."""
    done: dict[Hashable, Any] = {}
    path = Path(path)
    if not path.exists():
        return done
    damaged = 0
    for record in _scan(path.read_bytes()):
        if record is DAMAGED:
            damaged += 1
        else:
            done[key(record)] = record
    if damaged:
        warnings.warn(f"{path}: skipped {damaged} damaged record(s) (cut short or corrupt); "
                      f"kept the {len(done)} valid ones (the damaged ones' trials run again)",
                      stacklevel=2)
    return done


def _drop_damaged(path: Path) -> None:
    """Rewrite a journal holding damaged records as its valid records only (framed,
    atomically), so that a damaged record is reported once, not on every resume."""
    records = list(_scan(path.read_bytes()))
    if not any(r is DAMAGED for r in records):
        return
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_bytes(b"".join(encode_record(r) for r in records if r is not DAMAGED))
    os.replace(tmp, path)


class Journal:
    """Append records to a journal file, each written whole and flushed at once (a
    context manager). An existing file with damaged records is first rewritten without
    them."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self.path.exists():
            _drop_damaged(self.path)
        self._file = open(self.path, "ab")  # noqa: SIM115 - closed in close()

    def append(self, record: Any) -> None:
        self._file.write(encode_record(record))
        self._file.flush()

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> Journal:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

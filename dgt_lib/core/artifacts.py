"""The artifact cache (docs/ARCHITECTURE.md → Artifacts).

Every pipeline stage stores its output under ``data/<profile>/…`` through
:func:`ensure`: the artifact is loaded when it exists and was built from the same
configuration, and built (then written atomically) otherwise. Beside each file
``X`` lies ``X.meta.json`` with the configuration hash, the file's size and its
SHA-256, so a mismatched configuration, a truncated or otherwise corrupt file is
detected, reported in one line and rebuilt — never silently used. A build holds an
exclusive lock on ``X.lock`` beside the file: a second run on the same data directory
waits for it and loads what it wrote instead of building it again.

Formats follow the file suffix: ``.npz`` (a dict of numpy arrays), ``.json``,
``.pt`` (``torch.save``), anything else pickle.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import pickle
import tempfile
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from tqdm import tqdm

from dgt_lib.core.cache_keys import KEY_FORM, jsonable
from dgt_lib.core.faults import STORAGE_ERRNOS

try:
    import fcntl
except ImportError:  # Windows: no advisory locks; runs on one data directory then race
    fcntl = None

T = TypeVar("T")

DATA_ENV_VAR = "DGT_DATA_DIR"
_REPO_ROOT = Path(__file__).resolve().parents[2]  # dgt_lib/core/artifacts.py → the repository


def data_root() -> Path:
    """``$DGT_DATA_DIR`` if set, else ``data/`` at the repository root."""
    return Path(os.environ.get(DATA_ENV_VAR, _REPO_ROOT / "data"))


def profile_dir(profile: str) -> Path:
    """``data/<profile>/``: where a profile's artifacts live."""
    return data_root() / profile


def config_hash(config: Any) -> str:
    """A stable 16-hex-digit hash of a configuration (dataclasses, dicts, numbers, arrays)
    in key form (:func:`dgt_lib.core.cache_keys.jsonable`: settings at their defaults left
    out)."""
    text = json.dumps(jsonable(config), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _file_digest(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _meta_path(path: Path) -> Path:
    return path.with_name(path.name + ".meta.json")


def new_file_mode() -> int:
    """The mode ``open()`` gives a new file here: ``0o666 & ~umask`` (0o644 under the
    usual umask 022, 0o664 under 002 for a group's shared directory). Read from
    ``/proc/self/status`` where it says, so no other thread sees a changed umask."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return 0o666 & ~int(line.split()[1], 8)
    except OSError:
        pass
    mask = os.umask(0o022)  # no /proc (macOS): read by setting and restoring
    os.umask(mask)
    return 0o666 & ~mask


def _atomic_write(path: Path, write: Callable[[Path], None],
                  needed_bytes: int | None = None, *, tmp_suffix: str = ".tmp") -> None:
    """Write through ``write(tmp_path)``, flush it to disk (``fsync``), then rename it over
    ``path`` and flush the directory: a crash, SIGKILL or power cut leaves the old file or
    the whole new one, never half a file. The temporary file lies in ``path``'s directory
    (a rename within one file system is atomic) and ends in ``tmp_suffix`` (for writers
    that pick a format by the suffix). The file gets :func:`new_file_mode` (the temporary
    file is private, 0o600, until then), so others sharing the data directory can read it
    (docs/reliability.md). A full disk, a read-only file system or a refused permission is
    an ``OSError`` naming ``path`` (not the temporary file) with ``needed_bytes`` when known
    (:func:`dgt_lib.core.faults.storage_message` says it in one line)."""
    tmp_path = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name[:80]}.",
                                   suffix=tmp_suffix)
        os.close(fd)
        tmp_path = Path(tmp)
        write(tmp_path)
        _fsync(tmp_path, os.O_RDONLY)
        os.chmod(tmp_path, new_file_mode())
        os.replace(tmp_path, path)
        _fsync(path.parent, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError as exc:
        if exc.errno not in STORAGE_ERRNOS:
            raise
        raise _naming(exc, path, needed_bytes) from exc
    finally:
        if tmp_path is not None and tmp_path.exists():
            tmp_path.unlink()


def fsync_path(path: Path) -> None:
    """Flush a file, or a directory's entries (a rename in it), to disk."""
    _fsync(path, os.O_RDONLY | (getattr(os, "O_DIRECTORY", 0) if path.is_dir() else 0))


def _fsync(path: Path, flags: int) -> None:
    """``fsync`` a file or directory by its path (a directory that refuses it is let be)."""
    fd = os.open(path, flags)
    try:
        os.fsync(fd)
    except OSError:
        if not path.is_dir():
            raise
    finally:
        os.close(fd)


def write_atomically(path: str | Path, write: Callable[[Path], None], *,
                     tmp_suffix: str = ".tmp") -> Path:
    """A file a user pointed the kit at (``dgt costmap --out``, ``dgt plan``'s figure),
    written as the cache writes its artifacts: under :func:`build_lock` (two writers of one
    path take turns, never mixing their bytes) through :func:`_atomic_write` (the target
    holds the old file or the whole new one). The lock beside it is hidden
    (``.<name>.lock``): a user's folder shows only what they asked for. Returns ``path``."""
    path = Path(path)
    with build_lock(path, hidden=True):
        _atomic_write(path, write, tmp_suffix=tmp_suffix)
    return path


def _naming(exc: OSError, path: Path, needed_bytes: int | None = None) -> OSError:
    """For a full, read-only or refused directory (``exc.errno`` in
    :data:`~dgt_lib.core.faults.STORAGE_ERRNOS`): the same error naming the artifact
    ``path`` — not a temporary file — with ``needed_bytes`` when known."""
    err = OSError(exc.errno, os.strerror(exc.errno), str(path))
    err.needed_bytes = needed_bytes
    return err


def _nbytes(value: Any) -> int | None:
    """The bytes of a dict of arrays (what an ``.npz`` holds, uncompressed), else None."""
    if isinstance(value, dict) and value and all(isinstance(v, np.ndarray)
                                                 for v in value.values()):
        return int(sum(v.nbytes for v in value.values()))
    return None


def save(path: Path, value: Any) -> None:
    """Write ``value`` atomically in the format given by ``path``'s suffix."""
    path = Path(path)
    suffix = path.suffix

    def write(tmp: Path) -> None:
        if suffix == ".npz":
            with open(tmp, "wb") as f:
                np.savez(f, **value)
        elif suffix == ".json":
            tmp.write_text(json.dumps(value, indent=1))
        elif suffix == ".pt":
            import torch

            torch.save(value, tmp)
        else:
            with open(tmp, "wb") as f:
                pickle.dump(value, f, protocol=pickle.HIGHEST_PROTOCOL)

    _atomic_write(path, write, _nbytes(value))


def load(path: Path) -> Any:
    """Read a file written by :func:`save` (every array is read into memory)."""
    path = Path(path)
    suffix = path.suffix
    if suffix == ".npz":
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    if suffix == ".json":
        return json.loads(path.read_text())
    if suffix == ".pt":
        import torch

        return torch.load(path, map_location="cpu", weights_only=False)
    with open(path, "rb") as f:
        return pickle.load(f)


def changed_settings(old: Any, new: Any, prefix: str = "", depth: int = 2) -> list[str]:
    """Dotted names of the settings that differ between two configurations in their
    :func:`config_hash` form (dicts compared key by key down to ``depth`` levels):
    ``["physics", "episode.speed_mps"]``. What a user wants to read when an artifact is
    rebuilt, instead of two hashes."""
    if old == new:
        return []
    if depth == 0 or not (isinstance(old, dict) and isinstance(new, dict)) or (
            "__array__" in old or "__array__" in new):  # an array is one setting
        return [prefix or "(whole configuration)"]
    out = []
    for key in sorted(set(old) | set(new)):
        if key == "__type__":
            continue
        name = f"{prefix}.{key}" if prefix else key
        if key not in old or key not in new:
            out.append(name)
        else:
            out += changed_settings(old[key], new[key], name, depth - 1)
    return out or [prefix or "(whole configuration)"]


def _check(path: Path, config: Any) -> str | None:
    """None when ``path`` is a valid artifact of ``config``; else why not, naming the
    settings that changed (:func:`changed_settings`)."""
    meta_path = _meta_path(path)
    if not path.exists():
        return "missing"
    if not meta_path.exists():
        return "no metadata beside it"
    try:
        meta = json.loads(meta_path.read_text())
    except (OSError, ValueError):
        return "unreadable metadata"
    if meta.get("config_hash") != config_hash(config):
        if meta.get("key_form") != KEY_FORM:
            return "stored by an older kit, whose keys held every setting"
        current, stored = jsonable(config), meta.get("config")
        if stored != current:
            return f"configuration changed ({', '.join(changed_settings(stored, current))})"
    if meta.get("size") != path.stat().st_size or meta.get("sha256") != _file_digest(path):
        return "corrupt (size or checksum differs from when it was written)"
    return None


def staleness(relpath: str | Path, config: Any, *, profile: str) -> str | None:
    """Why :func:`ensure` would rebuild this artifact ("missing", "configuration changed
    (physics)", "corrupt …"), or None when it would load it."""
    return _check(profile_dir(profile) / Path(relpath), config)


def report_rebuilds(reasons: list[str | None], what: str,
                    log: Callable[[str], None] = tqdm.write) -> None:
    """One line for many artifacts of one kind about to be rebuilt, e.g. "[dgt] 130
    episodes (demo) to rebuild: configuration changed (physics)", instead of a line
    each; nothing when all are missing (a first run) or fresh."""
    stale = [r for r in reasons if r is not None and r != "missing"]
    if not stale:
        return
    counts = Counter(stale)  # in the order first seen
    parts = [f"{n} {reason}" if len(counts) > 1 else reason for reason, n in counts.items()]
    log(f"[dgt] {len(stale)} {what} to rebuild: {'; '.join(parts)}")


def ensure(
    relpath: str | Path,
    config: Any,
    build: Callable[[], T],
    *,
    profile: str,
    log: Callable[[str], None] = tqdm.write,
    fingerprint: Callable[[T], str] | None = None,
) -> T:
    """Load ``data/<profile>/<relpath>`` if it was built from ``config``; else build and save it.

    ``build()`` returns the value to store (a dict of arrays for ``.npz``). A
    mismatched hash, a missing metadata file or a corrupt artifact prints one line
    saying why, and the artifact is rebuilt. ``fingerprint(value)``, when given, is a
    digest of what the value means (a model's weights, not its training's timings),
    recorded in the metadata when it is built; :func:`stored_digest` returns it in
    place of the file's SHA-256, so the artifacts built on this one are keyed by content.
    """
    path = profile_dir(profile) / Path(relpath)
    why, value = _load_if_fresh(path, config)
    if why is None:
        return value
    with build_lock(path):  # one run builds it; another waits, then loads what it wrote
        why, value = _load_if_fresh(path, config)
        if why is None:
            return value
        if why != "missing":
            log(f"[dgt] rebuilding {path}: {why}")
        value = build()
        save(path, value)
        meta = {"config_hash": config_hash(config), "size": path.stat().st_size,
                "sha256": _file_digest(path), "config": jsonable(config),
                "key_form": KEY_FORM}
        if fingerprint is not None:
            meta["fingerprint"] = fingerprint(value)
        _atomic_write(_meta_path(path), lambda tmp: tmp.write_text(json.dumps(meta, indent=1)))
    return value


def _load_if_fresh(path: Path, config: Any) -> tuple[str | None, Any]:
    """``(None, value)`` for a valid artifact of ``config``, else ``(why not, None)``."""
    why = _check(path, config)
    if why is None:
        try:
            return None, load(path)
        except Exception as exc:  # noqa: BLE001 - any failure to read means rebuild
            why = f"corrupt ({type(exc).__name__}: {exc})"
    return why, None


@contextlib.contextmanager
def build_lock(path: Path, *, hidden: bool = False) -> Iterator[None]:
    """Hold an exclusive lock on ``<path>.lock`` beside the artifact while it is built:
    runs sharing a data directory build it once (the others wait here, then load it)
    instead of reading it half-way through and calling it corrupt. Inside, the directory
    is known to be writable: a read-only or refused one raises its ``OSError`` (naming
    ``path``) before anything is built. The lock file stays (removing it would let a
    waiting run and a new one lock different files); ``hidden`` names it ``.<name>.lock``,
    for files in a user's folder."""
    lock = path.with_name(("." if hidden else "") + path.name + ".lock")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        # read-only suffices to lock, so a lock file another user made can be locked too
        fd = os.open(lock, os.O_RDONLY | os.O_CREAT, 0o666)
    except OSError as exc:
        if exc.errno not in STORAGE_ERRNOS:
            raise
        raise _naming(exc, path) from exc
    try:
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX)  # released when fd is closed
        try:  # a lock file made earlier opens on a read-only file system: try a file
            probe, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name[:80]}.",
                                           suffix=".probe")
        except OSError as exc:
            if exc.errno not in STORAGE_ERRNOS:
                raise
            raise _naming(exc, path) from exc
        os.close(probe)
        os.unlink(name)
        yield
    finally:
        os.close(fd)


def stored_digest(relpath: str | Path, *, profile: str) -> str:
    """The fingerprint recorded when ``data/<profile>/<relpath>`` was written (see
    :func:`ensure`), else its SHA-256: a cheap digest of an artifact for the
    configuration of the stages built on it."""
    meta_path = _meta_path(profile_dir(profile) / Path(relpath))
    try:
        meta = json.loads(meta_path.read_text())
        return meta.get("fingerprint") or meta["sha256"]
    except (OSError, ValueError, KeyError) as exc:
        raise FileNotFoundError(f"no valid artifact at {meta_path.with_suffix('')}: {exc}") from exc


def fresh_fingerprint(relpath: str | Path, config: Any, *, profile: str) -> str | None:
    """The fingerprint recorded by :func:`ensure` for a fresh artifact, read from its
    metadata without loading it; None when :func:`ensure` would rebuild the artifact or
    no fingerprint was recorded."""
    path = profile_dir(profile) / Path(relpath)
    if _check(path, config) is not None:
        return None
    return json.loads(_meta_path(path).read_text()).get("fingerprint")


def is_fresh(relpath: str | Path, config: Any, *, profile: str) -> bool:
    """Whether :func:`ensure` would load (not build) this artifact."""
    return staleness(relpath, config, profile=profile) is None

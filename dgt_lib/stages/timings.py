"""The wall time of every stage ``dgt reproduce`` runs, kept beside the profile's outputs.

Each finished stage appends one JSON line to ``data/<profile>/stage_times.jsonl``: when it
started (UTC), the seed, the stage, its wall time [s], the machine's 1-minute load average
when it started, the CPU count and how the jobs ran. Appending per stage keeps what
finished when a run is interrupted or crashes later, and a stage that was already cached
shows as a fraction of a second. On a data directory that cannot be written (read-only,
full) the times are not recorded, with one note on stderr, and the run goes on. A run's
per-stage breakdown (``benchmarks/stage_times.py``, a published run's records) can then be
quoted from what the code wrote.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

from dgt_lib.core.config import Profile, as_profile
from dgt_lib.core.faults import is_storage_error
from dgt_lib.core.overrides import format_setting
from dgt_lib.stages.paths import profile_root

STAGE_TIMES_NAME = "stage_times.jsonl"
"""File name of the stage-time log in the profile's directory."""


def stage_times_path(profile: Profile | str | None) -> Path:
    """``data/<profile>/stage_times.jsonl``."""
    return profile_root(profile) / STAGE_TIMES_NAME


def machine_load() -> float | None:
    """The 1-minute load average, or None where the OS has none (Windows)."""
    try:
        return round(os.getloadavg()[0], 2)
    except (AttributeError, OSError):
        return None


def utc_text(unix_s: float) -> str:
    """``unix_s`` [s since the epoch] as ISO 8601 UTC to the second."""
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(unix_s))


def new_run_id() -> str:
    """A name for one ``dgt reproduce`` invocation: its start, UTC to the microsecond."""
    now = time.time()
    return f"{utc_text(now)[:-1]}.{int(now % 1 * 1e6):06d}Z"


def record_stage_time(profile: Profile, stage: str, seconds: float, *, run: str,
                      started_unix_s: float, load_before: float | None) -> dict:
    """Append one stage's record to :func:`stage_times_path` and return it.

    ``profile`` is the seed's profile (its ``seed`` is recorded); ``seconds`` the stage's
    wall time; ``run`` names the ``dgt reproduce`` invocation (:func:`new_run_id`);
    ``started_unix_s`` when the stage started [s since the epoch]; ``load_before`` the
    1-minute load average then (:func:`machine_load`). A run with changed settings
    (``--set``) records them, so its times are kept apart from the profile's own."""
    prof = as_profile(profile)
    record = {
        "run": run, "started_utc": utc_text(started_unix_s),
        "profile": prof.name, "seed": prof.seed, "stage": stage,
        "seconds": round(float(seconds), 1), "load_1min_before": load_before,
        "cpus": os.cpu_count(), "workers": prof.workers,
        "executor": prof.execution.executor, "device": prof.execution.device,
        "overrides": {k: format_setting(v) for k, v in prof.overrides},  # --set, if any
    }
    path = stage_times_path(prof)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("a", encoding="utf-8") as f:
            f.write(json.dumps(record, ensure_ascii=False) + "\n")
    except OSError as exc:
        if not is_storage_error(exc):
            raise
        if path not in _UNWRITABLE:  # said once: a cached run on a read-only directory
            _UNWRITABLE.add(path)
            print(f"[dgt] stage times not recorded: cannot write {path} ({exc.strerror}); "
                  "the summary shows them", file=sys.stderr)
    return record


_UNWRITABLE: set[Path] = set()
"""Stage-time logs this process could not write (each noted once)."""


def read_stage_times(profile: Profile | str | None) -> list[dict]:
    """Every record of the profile's stage-time log, oldest first ([] when there is none).
    A line cut short by a crash while it was written is skipped."""
    path = stage_times_path(profile)
    if not path.exists():
        return []
    records = []
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            records.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return records

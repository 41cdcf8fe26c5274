"""Publish a profile's run records into ``docs/runs/<profile>_<processor>_<date>/``.

    python -m dgt_lib.records publish --profile demo --seeds 8   # after dgt reproduce

Each seed's record (``results/summary.json``) is copied as ``seed-<s>.json`` with the
wall times of the stages that ran for it (``stage_times.jsonl``). A run is one profile on
one processor: records of several processors are refused, so that a table never pools
them without saying so.
"""

from __future__ import annotations

import json
from pathlib import Path

from dgt_lib.core.config import Profile, as_profile
from dgt_lib.records.provenance import ROOT, processor_slug
from dgt_lib.records.record import seed_summaries
from dgt_lib.records.study import write_record
from dgt_lib.stages.timings import read_stage_times

RUNS = ROOT / "docs" / "runs"
"""Where published runs live in the checkout."""


def stage_times(profile: str, seed: int) -> list[dict]:
    """The stage-time entries of one seed (every invocation of the profile's own settings:
    not those run with ``--set``), oldest first, trimmed to stage, seconds, load and start."""
    keep = ("stage", "seconds", "load_1min_before", "started_utc")
    return [{k: r.get(k) for k in keep} for r in read_stage_times(profile)
            if r.get("seed") == seed and r.get("profile") == profile and not r.get("overrides")]


def run_name(records: list[dict]) -> str:
    """``<profile>_<processor slug>_<date of the newest record>``; ValueError when the
    records come from several processors or profiles."""
    procs = {json.dumps(r["processor"], sort_keys=True) for r in records}
    profiles = {r["profile"] for r in records}
    if len(procs) > 1 or len(profiles) > 1:
        raise ValueError("these records come from several processors or profiles: publish "
                         "each machine's run on its own")
    date = max(r["date_utc"] for r in records)[:10]
    return f"{records[0]['profile']}_{processor_slug(records[0]['processor'])}_{date}"


def publish(profile: Profile | str, dest: Path = RUNS) -> Path:
    """Copy every seed's record of ``profile`` (all its seeds must have one: a run of
    ``--seeds 8`` is published with ``profile.with_(seeds=8)``) with its stage times into
    a new run folder under ``dest``; returns the folder."""
    prof = as_profile(profile)
    records = seed_summaries(prof, require_all=True)
    changed = [r["seed"] for r in records if r.get("overrides")]
    if changed:
        raise ValueError(f"seed(s) {changed} hold a run with changed settings: rerun "
                         f"`dgt reproduce --profile {prof.name} --seed S --stages experiments`"
                         " to write the profile's own record first")
    folder = dest / run_name(records)
    for record in records:
        write_record(folder / f"seed-{record['seed']}.json",
                     {**record, "stage_times": stage_times(prof.name, record["seed"])},
                     f"seed {record['seed']}'s record")
    return folder

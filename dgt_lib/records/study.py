"""A study's record: the tables a script of ``studies/`` measured, with where it ran.

A study that backs a page of the docs publishes its result as one JSON file,
``docs/runs/studies/<study>_<profile>_<processor>_<date>.json``::

    {"schema": 1, "commit": …, "processor": {…}, "versions": {…}, "date_utc": …,
     "study": "controller_ablation", "profile": "demo", "seeds": [0, 1, 2],
     "command": "python studies/controller_ablation.py --profile demo --seeds 3 --publish",
     "tables": {"experiment1": {"title": …, "columns": […], "rows": [[…], …]}, …},
     "lists": {"experiment1_failures": ["…", …]}}

A page quotes a table or a list of it in a generated block named after the record's file
and the table::

    <!-- generated: study:controller_ablation_demo_amd-epyc-f25m1_2026-11-28/experiment1 -->
    <!-- end generated: study:controller_ablation_demo_amd-epyc-f25m1_2026-11-28/experiment1 -->

and ``make docs`` renders it, with a caption naming the profile, seeds, processor, commit
and the record (:func:`render_block`). The study formats its own cells; this module only
lays them out, so the same record always renders the same text.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path

from dgt_lib.records.provenance import ROOT, processor_label, processor_slug, provenance

SCHEMA = 1
"""The study record format's version: raised when a field changes meaning."""

STUDIES = ROOT / "docs" / "runs" / "studies"
"""Where published study records live in the checkout."""

MAX_RECORD_BYTES = 50_000
"""The largest record the repository takes [bytes]."""

BLOCK_PREFIX = "study:"
"""A generated block whose name starts so is a study's table or list."""


def table(title: str, columns: Sequence[str], rows: Sequence[Sequence[object]]) -> dict:
    """One table of a record: every cell as the text the page shows; ValueError for a
    row of another width than ``columns``."""
    for row in rows:
        if len(row) != len(columns):
            raise ValueError(f"{title}: a row of {len(row)} cells under {len(columns)} columns")
    return {"title": title, "columns": list(columns),
            "rows": [[str(cell) for cell in row] for row in rows]}


def study_record(study: str, profile: str, seeds: Sequence[int], tables: dict[str, dict],
                 lists: dict[str, list[str]] | None = None,
                 argv: Sequence[str] | None = None, variant: str = "",
                 script: str | None = None, load: tuple[float, float] | None = None) -> dict:
    """The record of one run of ``studies/<study>.py`` (or of ``script``, a path in the
    checkout): provenance, profile, seeds, the command that made it, its tables
    (:func:`table`) and lists of lines; ``variant`` names one of a study's several records
    (``hazard``), kept apart in the file name. A benchmark also gives ``load``: the
    1-minute load average when it started and when it ended (its times are only as good
    as the machine was idle); its profile is "" when it times no profile's artifacts."""
    args = sys.argv[1:] if argv is None else argv
    return {"schema": SCHEMA, **provenance(), "study": study, "variant": variant,
            "profile": profile, "seeds": [int(s) for s in seeds],
            "command": shlex.join(["python", script or f"studies/{study}.py", *args]),
            **({"load": [round(v, 2) for v in load]} if load else {}),
            "tables": tables, "lists": lists or {}}


def record_name(record: dict) -> str:
    """``<study>[-<variant>]_<profile>_<processor slug>_<date>`` (no profile part for a
    benchmark of none): the record's file stem."""
    study = record["study"] + (f"-{record['variant']}" if record.get("variant") else "")
    profile = re.sub(r"[^\w.]+", "-", record["profile"])  # "smoke, demo" → smoke-demo
    return "_".join(part for part in (study, profile, processor_slug(record["processor"]),
                                      record["date_utc"][:10]) if part)


def publish_study(record: dict, dest: Path | None = None) -> Path:
    """Write ``record`` to ``dest/<record_name>.json`` (default :data:`STUDIES`) whole or
    not at all; its path. ValueError for a record over :data:`MAX_RECORD_BYTES`."""
    path = (STUDIES if dest is None else dest) / f"{record_name(record)}.json"
    return write_record(path, record, f"the {record['study']} record")


def write_record(path: Path, record: dict, what: str) -> Path:
    """Write a run's or a study's ``record`` as JSON to ``path``, whole or not at all (a
    temporary file renamed over it); ValueError, naming ``what``, for one over
    :data:`MAX_RECORD_BYTES`."""
    text = json.dumps(record, indent=1, ensure_ascii=False) + "\n"
    if len(text.encode()) > MAX_RECORD_BYTES:
        raise ValueError(f"{what} is {len(text.encode())} bytes, over {MAX_RECORD_BYTES}: "
                         "keep fewer tables or rows")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    return tmp.replace(path)


def _seeds(seeds: Sequence[int]) -> str:
    if not seeds:
        return "no run's artifacts (the worlds alone)"
    if len(seeds) > 2 and list(seeds) == list(range(seeds[0], seeds[-1] + 1)):
        return f"seeds {seeds[0]}–{seeds[-1]}"
    return f"seed{'s' if len(seeds) != 1 else ''} " + ", ".join(map(str, seeds))


def caption(record: dict, link: str) -> str:
    """What a study's table rests on: profile, seeds, processor (and a benchmark's load
    average), commit, command, record."""
    load, seeds = record.get("load"), record["seeds"]  # a benchmark may time a cache: no seeds
    run = "" if not record["profile"] else f"`{record['profile']}`, " + (
        "" if load and not seeds else f"{_seeds(seeds)}, ")
    load = ", load average {:.1f} → {:.1f}".format(*load) if load else ""
    return (f"*{run}{processor_label(record['processor'])}{load}, commit `{record['commit'][:7]}`"
            f": `{record['command']}`; record: [{Path(link).name}]({link})*")


def render_table(tab: dict) -> str:
    """A table of a record as Markdown, its title in bold above it."""
    lines = [f"**{tab['title']}**", "", "| " + " | ".join(tab["columns"]) + " |",
             "|" + "---|" * len(tab["columns"])]
    lines += ["| " + " | ".join(row) + " |" for row in tab["rows"]]
    return "\n".join(lines) + "\n"


def render_block(name: str, page: Path, root: Path = ROOT) -> str:
    """The Markdown of the generated block ``study:<record>/<part>`` on ``page``: the
    record's table or list ``part`` and its caption. FileNotFoundError for a record that
    is not published, ValueError for a part the record does not hold."""
    stem, _, part = name.removeprefix(BLOCK_PREFIX).partition("/")
    path = root / "docs" / "runs" / "studies" / f"{stem}.json"
    if not path.exists():
        raise FileNotFoundError(f"{page.relative_to(root)}: block {name!r} cites a study record "
                                f"that is not published ({path.relative_to(root)})")
    record = json.loads(path.read_text())
    link = Path(os.path.relpath(path, page.parent)).as_posix()
    if part in record["tables"]:
        body = render_table(record["tables"][part])
    elif part in record["lists"]:
        body = "\n".join(f"- {line}" for line in record["lists"][part] or ["none"]) + "\n"
    else:
        raise ValueError(f"{page.relative_to(root)}: {path.name} has no table or list "
                         f"{part!r} (it has {sorted(record['tables']) + sorted(record['lists'])})")
    return body + "\n" + caption(record, link) + "\n"

"""How long a person waits for each notebook: every notebook run top to bottom in a fresh
kernel, as ``Run All`` would, under a profile.

    .venv/bin/python benchmarks/bench_notebooks.py --profile demo
    .venv/bin/python benchmarks/bench_notebooks.py --profile demo --notebooks 03 04 --cells 5

Prints one row per notebook (wall seconds, its slowest cells) and the total; ``--publish``
writes them as a record (``benchmarks/publish.py``) that docs/speed.md quotes and the
notebooks' *Time* notes link to. The notebooks
read the profile's artifact cache; a notebook whose artifacts are not cached builds them
first (the pipeline's stages), so time a warm cache — run ``dgt reproduce --profile P
--seeds 1`` before — unless that first wait is what you want to measure. The executed
copies go to a temporary directory (``--keep DIR`` keeps them); ``notebooks/`` is never
written. What a notebook writes under ``data/`` (its rerun recordings) is written as usual.
"""

from __future__ import annotations

import argparse
import datetime as dt
import os
import sys
import tempfile
import time
from pathlib import Path

import nbformat
from nbclient import NotebookClient
from publish import Benchmark

from dgt_lib.core.config import get_profile
from dgt_lib.records.record import SUMMARY_NAME
from dgt_lib.records.study import table
from dgt_lib.stages.paths import results_dir

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOKS = ROOT / "notebooks"


def _cell_seconds(cell) -> float | None:
    """Wall seconds a code cell ran, from the timing nbclient records in its metadata."""
    t = cell.get("metadata", {}).get("execution", {})
    try:
        start = dt.datetime.fromisoformat(t["iopub.execute_input"].replace("Z", "+00:00"))
        end = dt.datetime.fromisoformat(t["shell.execute_reply"].replace("Z", "+00:00"))
    except KeyError:
        return None
    return (end - start).total_seconds()


def _first_line(cell) -> str:
    lines = [s for s in "".join(cell.source).splitlines() if s.strip() and not s.startswith("#")]
    text = lines[0].replace("|", "\\|") if lines else ""  # a table cell
    return text if len(text) <= 60 else text[:57] + "..."


def run_notebook(path: Path, profile: str, timeout_s: int, keep: Path) -> tuple[float, list]:
    """Execute ``path`` under ``profile``; its wall seconds and ``(seconds, cell index,
    first line)`` of each code cell, slowest first. Raises if a cell fails."""
    nb = nbformat.read(path, as_version=4)
    client = NotebookClient(nb, timeout=timeout_s, kernel_name="python3",
                            resources={"metadata": {"path": str(NOTEBOOKS)}})
    start = time.perf_counter()
    try:  # the kernel's environment: this process's, with the profile
        client.execute(env={**os.environ, "DGT_PROFILE": profile})
    finally:
        wall = time.perf_counter() - start
        nbformat.write(nb, keep / path.name)
    cells = [(_cell_seconds(c), i, _first_line(c)) for i, c in enumerate(nb.cells)
             if c.cell_type == "code"]
    return wall, sorted((c for c in cells if c[0] is not None), reverse=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", default="demo", choices=("smoke", "demo", "paper"))
    parser.add_argument("--notebooks", nargs="*", default=None,
                        help="names or number prefixes (e.g. 03 04); default: all")
    parser.add_argument("--cells", type=int, default=2, help="slowest cells shown per notebook")
    parser.add_argument("--timeout", type=int, default=1800, help="per cell [s]")
    parser.add_argument("--keep", type=Path, default=None,
                        help="directory for the executed copies (default: a temporary one)")
    bench = Benchmark("bench_notebooks", parser)
    args = parser.parse_args()

    paths = sorted(NOTEBOOKS.glob("[0-9][0-9]*_*.ipynb"))
    if args.notebooks:
        paths = [p for p in paths if any(p.stem.startswith(n) or p.name == n
                                         for n in args.notebooks)]
        if not paths:
            sys.exit(f"no notebook matches {args.notebooks} in {NOTEBOOKS}")
    keep = args.keep or Path(tempfile.mkdtemp(prefix="bench_notebooks_"))
    keep.mkdir(parents=True, exist_ok=True)
    warm = (results_dir(get_profile(args.profile)) / SUMMARY_NAME).exists()
    print(f"profile {args.profile} ({'warm: seed 0 has run' if warm else 'seed 0 not run'}), "
          f"{os.cpu_count()} CPUs; executed copies in {keep}\n")
    rows, total = [], 0.0
    for path in paths:
        wall, cells = run_notebook(path, args.profile, args.timeout, keep)
        total += wall
        slow = "; ".join(f"{s:.0f} (cell {i}: `{line}`)" for s, i, line in cells[:args.cells])
        rows.append([path.stem, f"{wall:.0f}", slow])
        print(" | ".join(rows[-1]), flush=True)
    rows.append([f"**all {len(paths)}**", f"**{total:.0f}**", ""])
    cache = ("seed 0's artifacts cached beforehand" if warm else
             "seed 0 not run before: the first notebooks build its artifacts")
    bench.finish({"notebooks": table(
        f"Each notebook top to bottom in a fresh kernel on `{args.profile}`, {cache}: wall "
        f"seconds, and its slowest code cells (index: first line)",
        ["notebook", "wall [s]", "slowest cells [s]"], rows)}, args.publish,
        profile=args.profile)


if __name__ == "__main__":
    main()

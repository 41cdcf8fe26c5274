"""How long a user waits for ``dgt plan``: the whole command in a fresh process, cached maps.

    .venv/bin/python benchmarks/bench_plan_query.py                 # demo, hill, carla_cola
    .venv/bin/python benchmarks/bench_plan_query.py --repeats 7 --profile paper
    PYTHONPATH=/other/checkout DGT_DATA_DIR=$PWD/data \
        .venv/bin/python benchmarks/bench_plan_query.py

The README's first query (``--world hill --vehicle carla_cola --start 30,14,0.8 --goal 30,96
--method dgt``) is planned once to fill the cache (BEV maps, model, costmaps), then
``--repeats`` times in fresh processes, as a user runs it: wall time of each (median
printed), and of ``import dgt_lib.app.plan_one`` alone (``-X importtime``'s total), and the
planner's own time as the command printed it; then the same query ``--repeats`` times
through ``dgt_lib.plan_query`` in this process, as a notebook calls it (imports paid
once). The commands run outside any checkout (in the temporary directory) with
``PYTHONPATH`` as given, so one script times two checkouts (give the other one this data
directory with ``DGT_DATA_DIR``). ``--publish`` writes the table's record
(``benchmarks/publish.py``) for docs/speed.md.
"""

from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import sys
import tempfile
import time

from publish import Benchmark

from dgt_lib.records.study import table

QUERY = ["--world", "hill", "--vehicle", "carla_cola", "--start", "30,14,0.8",
         "--goal", "30,96", "--method", "dgt"]


def timed(cmd: list[str]) -> tuple[float, str]:
    """Wall time [s] of ``cmd`` and what it printed."""
    t0 = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, check=True,
                         cwd=tempfile.gettempdir())  # not a checkout: PYTHONPATH decides
    return time.perf_counter() - t0, out.stdout + out.stderr


def import_seconds() -> float:
    """``import dgt_lib.app.plan_one`` in a fresh process, from ``-X importtime`` [s]."""
    _, log = timed([sys.executable, "-X", "importtime", "-c", "import dgt_lib.app.plan_one"])
    row = [line for line in log.splitlines() if line.rstrip().endswith("| dgt_lib.app.plan_one")]
    return int(row[-1].split("|")[1]) / 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--profile", default="demo")
    ap.add_argument("--repeats", type=int, default=5)
    bench = Benchmark("bench_plan_query", ap)
    args = ap.parse_args()
    cmd = [sys.executable, "-m", "dgt_lib", "plan", *QUERY, "--profile", args.profile]
    _, where = timed([sys.executable, "-c", "import dgt_lib; print(dgt_lib.__file__)"])
    print(f"dgt_lib from {where.strip()}; dgt plan {' '.join(QUERY)} --profile {args.profile}")
    timed(cmd)  # fills the cache (and numba's) if needed
    walls, searches, imports = [], [], []
    for _ in range(args.repeats):
        wall, out = timed(cmd)
        walls.append(wall)
        found = re.search(r"expansions, ([0-9.]+) s", out)
        searches.append(float(found.group(1)) if found else float("nan"))
        imports.append(import_seconds())
    from dgt_lib.app.plan_one import plan_query

    start, goal = (30.0, 14.0, 0.8), (30.0, 96.0)
    calls = []
    for _ in range(args.repeats + 1):
        t0 = time.perf_counter()
        plan_query("hill", "carla_cola", start, goal, method="dgt", profile=args.profile)
        calls.append(time.perf_counter() - t0)
    med = statistics.median
    rows = [["`dgt plan`, the whole command in a fresh process", f"**{med(walls):.2f} s**",
             ", ".join(f"{w:.2f}" for w in walls)],
            ["of which `import dgt_lib.app.plan_one`", f"{med(imports):.2f} s",
             ", ".join(f"{w:.2f}" for w in imports)],
            ["of which the Hybrid A* search", f"{med(searches):.2f} s",
             ", ".join(f"{w:.2f}" for w in searches)],
            ["`plan_query` again in one process (a notebook)", f"{med(calls[1:]):.2f} s",
             f"first call {calls[0]:.2f}, then " + ", ".join(f"{w:.2f}" for w in calls[1:])]]
    bench.finish({"plan": table(
        f"`dgt plan {' '.join(QUERY)}`, maps cached (median of {args.repeats})",
        ["what", "median", "each run [s]"], rows)}, args.publish, profile=args.profile)

if __name__ == "__main__":
    main()

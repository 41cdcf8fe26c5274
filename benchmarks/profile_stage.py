"""Where a stage's time goes: one stage of ``dgt reproduce`` under cProfile.

    .venv/bin/python benchmarks/profile_stage.py collect --profile smoke --data-dir /tmp/prof
    .venv/bin/python benchmarks/profile_stage.py costmaps --profile demo --data-dir /tmp/prof

The stages before it run first, unprofiled (a data directory that already holds them
reuses them); then the stage runs in this process with one worker, so that cProfile sees
the jobs a process pool would run elsewhere. Its own artifacts must not be cached yet: pass
a fresh ``--data-dir``, or one where only the earlier stages ran. Prints the functions with
the most time of their own, that time summed by where the code lives (a ``dgt_lib``
sub-package, a library such as mujoco, torch or numpy), and the stage's wall time with the
machine's load. Profiling slows pure-Python code more than compiled code, so read the
shares, not the seconds.
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import re
import time
from collections import defaultdict
from pathlib import Path


def where(path: str, function: str) -> str:
    """The place a profiled function belongs to: ``dgt_lib.<sub-package>``, a library's
    name, or ``built-in: <the C function's module>``."""
    if "dgt_lib/" in path:
        parts = path.split("dgt_lib/", 1)[1].split("/")
        return "dgt_lib." + (parts[0] if len(parts) > 1 else "(top level)")
    if "site-packages/" in path:
        return path.split("site-packages/", 1)[1].split("/")[0]
    if path == "~":  # a C function: "<built-in method mujoco._functions.mj_step>"
        found = re.search(r"(?:method|function) ([\w.]+)|of '([\w.]+)", function)
        name = next((g for g in found.groups() if g), "") if found else ""
        return f"built-in: {name.split('.')[0] or function}"
    return "python"


def profile_stage(stage: str, profile: str, seed: int, top: int) -> None:
    """Run the stages before ``stage`` (cached), then ``stage`` under cProfile; print."""
    from dgt_lib.core.config import get_profile
    from dgt_lib.stages import registry

    prof = get_profile(profile).with_(seed=seed, workers=1)
    stages = registry.select(None)
    names = [s.name for s in stages]
    if stage not in names:
        raise SystemExit(f"unknown stage {stage!r}; stages: {', '.join(names)}")
    for before in stages[: names.index(stage)]:
        print(f"[profile_stage] {before.name} (not profiled)", flush=True)
        before.run(prof)
    profiler = cProfile.Profile()
    load = os.getloadavg()[0]
    start = time.perf_counter()
    profiler.enable()
    stages[names.index(stage)].run(prof)
    profiler.disable()
    wall = time.perf_counter() - start
    stats = pstats.Stats(profiler)
    own = {key: row[2] for key, row in stats.stats.items()}  # (file, line, name) → tottime
    total = sum(own.values())
    print(f"\n{stage} ({profile}, seed {seed}, one worker): {wall:.1f} s wall under "
          f"cProfile, load {load:.1f} at the start on {os.cpu_count()} CPUs")
    if wall < 2.0:
        print("  (that fast: its artifacts were probably cached; use a fresh --data-dir)")
    print(f"\nthe {top} functions with the most time of their own:")
    for (path, line, name), seconds in sorted(own.items(), key=lambda kv: -kv[1])[:top]:
        place = f"{Path(path).name}:{line}" if path != "~" else "C"
        print(f"  {100 * seconds / total:5.1f} %  {seconds:7.2f} s  {name[:60]}  ({place})")
    groups: dict[str, float] = defaultdict(float)
    for (path, _, name), seconds in own.items():
        groups[where(path, name)] += seconds
    print("\nby where the code lives:")
    for place, seconds in sorted(groups.items(), key=lambda kv: -kv[1])[:top]:
        print(f"  {100 * seconds / total:5.1f} %  {seconds:7.2f} s  {place}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("stage", help="collect, bev, dataset, train, costmaps, ground_truth, …")
    ap.add_argument("--profile", default="smoke", help="smoke | demo | paper")
    ap.add_argument("--seed", type=int, default=0, help="the run seed")
    ap.add_argument("--data-dir", type=Path, required=True,
                    help="the data directory (earlier stages cached or built here)")
    ap.add_argument("--top", type=int, default=20, help="rows per table")
    args = ap.parse_args()
    os.environ["DGT_DATA_DIR"] = str(args.data_dir)
    os.environ.setdefault("MUJOCO_GL", "egl")
    profile_stage(args.stage, args.profile, args.seed, args.top)


if __name__ == "__main__":
    main()

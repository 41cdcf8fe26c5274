"""Where a whole ``dgt reproduce`` run's wall time went, per seed and stage.

Every stage ``dgt reproduce`` finishes appends its wall time (and the load average when it
started) to ``data/<profile>/stage_times.jsonl`` (``dgt_lib.stages.timings``). This prints
the latest run's breakdown as a markdown table, with each seed's total::

    dgt reproduce --profile paper --seeds 1        # from an empty data directory
    .venv/bin/python benchmarks/stage_times.py --profile paper

A stage that was already cached takes a fraction of a second, so time a whole seed from an
empty data directory (``DGT_DATA_DIR``) on idle cores; the load column says whether they
were.
"""

from __future__ import annotations

import argparse

from dgt_lib.stages.timings import read_stage_times, stage_times_path


def last_run(records: list[dict]) -> list[dict]:
    """The records of the latest ``dgt reproduce`` invocation in ``records``."""
    return [r for r in records if r.get("run") == records[-1].get("run")] if records else []


def stage_time_table(records: list[dict]) -> str:
    """A markdown table of ``records`` (one row each, in the order they ran) with each
    seed's total wall time."""
    if not records:
        return "(no stage times recorded)"
    lines = ["| seed | stage | wall [s] | load before | started (UTC) |",
             "| --- | --- | --- | --- | --- |"]
    totals: dict[int, float] = {}
    for r in records:
        load = "—" if r.get("load_1min_before") is None else f"{r['load_1min_before']:.2f}"
        lines.append(f"| {r['seed']} | {r['stage']} | {r['seconds']:,.1f} | {load} | "
                     f"{r['started_utc']} |")
        totals[r["seed"]] = totals.get(r["seed"], 0.0) + r["seconds"]
    for seed, total in totals.items():
        lines.append(f"| {seed} | **total** | **{total:,.1f}** | | |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", default="demo")
    parser.add_argument("--all", action="store_true",
                        help="every recorded run, not only the latest")
    args = parser.parse_args()
    records = read_stage_times(args.profile)
    if not records:
        raise SystemExit(f"no stage times in {stage_times_path(args.profile)}: run "
                         f"`dgt reproduce --profile {args.profile}` first")
    shown = records if args.all else last_run(records)
    print(f"{stage_times_path(args.profile)} — run started {shown[0]['run']}, "
          f"{shown[0]['cpus']} CPUs, {shown[0]['workers']} workers "
          f"({shown[0]['executor']}), device {shown[0]['device']}\n")
    print(stage_time_table(shown))


if __name__ == "__main__":
    main()

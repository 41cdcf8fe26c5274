"""What a benchmark that backs a docs table shares: its ``--publish`` switch and its record.

    from publish import Benchmark

    bench = Benchmark("bench_control", parser)   # adds --publish, notes the load now
    args = parser.parse_args()
    …
    bench.finish({"rate": table(…)})           # prints; with --publish writes the record

The record is a study record (:mod:`dgt_lib.records.study`) with the load average at the
start and at the end beside the processor, written to ``docs/runs/studies/``; a page quotes
its tables in ``<!-- generated: study:<record>/<table> -->`` blocks and ``make docs``
renders them with a caption naming processor, load, commit and command. A time measured on
a busy machine is a poor time: read the load before trusting one.
"""

from __future__ import annotations

import argparse
import os
import sys

from dgt_lib.records.study import publish_study, render_table, study_record


class Benchmark:
    """One benchmark script's ``--publish`` and its record."""

    def __init__(self, name: str, parser: argparse.ArgumentParser) -> None:
        self.name = name
        self.argv = list(sys.argv[1:])
        parser.add_argument("--publish", action="store_true",
                            help="also write the figures' record to docs/runs/studies/")
        self.load_start = os.getloadavg()[0]

    def finish(self, tables: dict[str, dict], publish: bool, profile: str = "") -> dict:
        """Print every table; with ``publish`` write the record (and say where).
        ``profile``: the profile whose cached artifacts it timed ("" for none)."""
        load = (self.load_start, os.getloadavg()[0])
        rerun = [a for a in self.argv if a != "--publish"] + ["--publish"]
        record = study_record(self.name, profile, [], tables, argv=rerun,
                              script=f"benchmarks/{self.name}.py", load=load)
        print(f"load average (1 min): {load[0]:.2f} at the start, {load[1]:.2f} at the end\n")
        for tab in tables.values():
            print(render_table(tab))
        if publish:
            path = publish_study(record)
            print(f"published {path}: quote its tables with <!-- generated: "
                  f"study:{path.stem}/<table> --> blocks and run `make docs`")
        return record

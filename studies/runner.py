"""What every study shares: its arguments (profile, run seeds, data directory) and its
record.

    from runner import Study

    study = Study("controller_ablation", __doc__)            # --profile, --seeds/--seed,
    study.parser.add_argument("--hazard", action="store_true")  # --data-dir, --publish
    args = study.parse()
    for seed in study.seeds: …
    study.finish({"experiment1": table(…)}, lists={…})

``finish`` prints the tables as Markdown; with ``--publish`` it also writes the study's
record to ``docs/runs/studies/`` (:mod:`dgt_lib.records.study`), which a docs page quotes in
a generated block and ``make docs`` renders.

Studies that rerun the pipeline with other settings (``map_inputs``, ``scarcity``) run each
variant in its own data directory, linked to what it shares with the profile's own run
(:func:`link`), in a process of its own, and store its scores as JSON so that a rerun
resumes (:func:`stored_or_run`, :func:`write_scores`).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

from dgt_lib.core.artifacts import DATA_ENV_VAR
from dgt_lib.core.config import PROFILE_NAMES, get_profile
from dgt_lib.core.faults import Terminated, sigterm_as_interrupt
from dgt_lib.records.study import publish_study, render_table, study_record

_HELD = contextlib.ExitStack()
"""What :meth:`Study.parse` sets up for the whole process (SIGTERM as Ctrl-C)."""


class Study:
    """One study script's command line and its record."""

    def __init__(self, name: str, doc: str | None, *, profile: str = "demo",
                 seeds: int | None = 3, per_seed: bool = True, several_profiles: bool = False,
                 publishes: bool = True, stores: bool = False) -> None:
        """``seeds``: how many run seeds by default (None: the profile's own count, as
        ``dgt reproduce``); ``per_seed=False``: no run seeds to choose; ``publishes=False``:
        the study only prints, and has no ``--publish``; ``stores=True``: the study keeps
        each evaluation as it finishes, and ``--stored`` prints (and publishes) from those
        alone."""
        self.name = name
        self.stores = stores
        self.several_profiles = several_profiles
        self.parser = argparse.ArgumentParser(
            prog=f"studies/{name}.py", description=(doc or name).strip(),
            formatter_class=argparse.RawDescriptionHelpFormatter)
        if several_profiles:
            self.parser.add_argument("--profile", action="append", choices=PROFILE_NAMES,
                                     default=None, help="repeatable (default: every profile)")
        else:
            self.parser.add_argument("--profile", default=profile, choices=PROFILE_NAMES)
        if per_seed:
            which = self.parser.add_mutually_exclusive_group()
            count = "the profile's count" if seeds is None else seeds
            which.add_argument("--seeds", type=int, default=seeds, metavar="N",
                               help=f"run seeds 0 … N-1 (default {count})")
            which.add_argument("--seed", type=int, action="append", default=None,
                               metavar="S", help="these run seeds instead (repeatable)")
        self.parser.add_argument("--data-dir", type=Path, default=None,
                                 help=f"the artifact cache to read (default ${DATA_ENV_VAR} "
                                      "or data/)")
        if publishes:
            self.parser.add_argument("--publish", action="store_true",
                                     help="also write the study's record to docs/runs/studies/")
        if stores:
            self.parser.add_argument("--stored", action="store_true",
                                     help="tables (and figure) from the evaluations already "
                                          "stored; compute nothing")
        self.args: argparse.Namespace | None = None

    def parse(self, argv: Sequence[str] | None = None) -> argparse.Namespace:
        """Parse the command line; ``--data-dir`` becomes the cache every stage reads. From
        here on SIGTERM (``kill``, a scheduler) stops the study as Ctrl-C does: training
        snapshots are written, temporary folders removed, stored scores kept."""
        _HELD.enter_context(sigterm_as_interrupt())  # for the life of the process
        sys.excepthook = _one_line_when_stopped(self.name, self.stores, sys.excepthook)
        self.argv = list(sys.argv[1:] if argv is None else argv)
        self.args = self.parser.parse_args(self.argv)
        if self.several_profiles and not self.args.profile:
            self.args.profile = list(PROFILE_NAMES)
        if self.args.data_dir is not None:
            os.environ[DATA_ENV_VAR] = str(self.args.data_dir)
        return self.args

    @property
    def seeds(self) -> list[int]:
        """The run seeds asked for: ``--seed`` as given, else 0 … ``--seeds``−1."""
        a = self.args
        if getattr(a, "seed", None):
            return list(a.seed)
        count = getattr(a, "seeds", 1)
        return list(range(get_profile(a.profile).seeds if count is None else count))

    def finish(self, tables: dict[str, dict], lists: dict[str, list[str]] | None = None,
               seeds: Sequence[int] | None = None, variant: str = "") -> dict:
        """Print every table and list; with ``--publish`` write the record (and say where).
        ``variant`` keeps one of the study's several records apart. Returns the record."""
        profile = self.args.profile
        # the command that reruns it from nothing: without --stored (which only reads what
        # an earlier run stored), with --publish once
        rerun = [a for a in self.argv if a not in ("--publish", "--stored")] + ["--publish"]
        record = study_record(self.name, ", ".join(profile) if self.several_profiles else profile,
                              self.seeds if seeds is None else seeds, tables, lists,
                              argv=rerun, variant=variant)
        for tab in tables.values():
            print(render_table(tab))
        for name, lines in (lists or {}).items():
            print(f"{name}:\n" + "\n".join(f"- {line}" for line in lines or ["none"]) + "\n")
        if getattr(self.args, "publish", False):
            path = publish_study(record)
            print(f"published {path}: quote its tables with <!-- generated: "
                  f"study:{path.stem}/<table> --> blocks and run `make docs`")
        return record


def _one_line_when_stopped(name: str, stores: bool, previous):
    """An exception hook that ends a study stopped by Ctrl-C or SIGTERM with one line, as
    ``dgt`` does, instead of a traceback; any other exception goes to ``previous``."""
    def hook(kind, value, traceback) -> None:
        if not issubclass(kind, KeyboardInterrupt):
            return previous(kind, value, traceback)
        how = "terminated" if isinstance(value, Terminated) else "interrupted"
        kept = ("every evaluation stored so far; the same command resumes from them" if stores
                else "nothing of this study; the profile's cached artifacts are untouched")
        print(f"studies/{name}.py: {how}. Kept: {kept}.", file=sys.stderr)
    return hook


def link(target: Path, link_path: Path) -> None:
    """``link_path`` → ``target`` (a file or directory of the profile's run), made once;
    nothing while ``target`` does not exist."""
    if link_path.is_symlink() or not target.exists():
        return
    link_path.parent.mkdir(parents=True, exist_ok=True)
    link_path.symlink_to(target.resolve(), target_is_directory=target.is_dir())


def stored_or_run(path: Path, root: Path, command: list[str], what: str) -> dict:
    """The JSON scores at ``path``; if missing, ``command`` runs first (``python`` + its
    arguments) with ``root`` as its data directory and must write them."""
    if path.exists():
        return json.loads(path.read_text())
    print(f"[{Path(command[0]).stem}] {what} in {root}", flush=True)
    subprocess.run([sys.executable, *command], env={**os.environ, DATA_ENV_VAR: str(root)},
                   check=True)
    return json.loads(path.read_text())


def write_scores(path: Path, scores: dict) -> None:
    """Store one variant's scores (written whole, then renamed: a crash leaves none)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(scores, indent=1))
    tmp.replace(path)

"""Tiny stages used by tests/test_cli.py to exercise `dgt reproduce`."""

import os
import time

from dgt_lib.core import artifacts
from dgt_lib.core.executors import current_executor, run_jobs
from dgt_lib.stages.paths import cache_dir, data_dir
from dgt_lib.stages.registry import StageOutput


def first(profile):
    artifacts.ensure("example.json", {"p": profile.name, "seed": profile.seed},
                     lambda: {"n": 1, "seed": profile.seed}, profile=cache_dir(profile))
    return StageOutput([data_dir(profile) / "example.json"], "wrote 1 file")


def second(profile):
    value = artifacts.load(data_dir(profile) / "example.json")
    return StageOutput([], f"read n={value['n']} of seed {value['seed']}")


def _job(index, seconds):
    pids = os.path.join(os.environ.get(artifacts.DATA_ENV_VAR, "."), "pids")
    os.makedirs(pids, exist_ok=True)
    open(os.path.join(pids, str(os.getpid())), "w").close()  # who ran it (test_cli)
    time.sleep(seconds)
    return index


def executor(profile):
    """Four quick jobs through whatever `dgt reproduce` chose; says which executor ran
    them and in how many processes."""
    pids = set(run_jobs(_pid_of, [(i,) for i in range(4)], workers=profile.workers,
                        progress=False).values())
    ex = current_executor()
    return StageOutput([], f"executor {type(ex).__name__ if ex else None} with "
                           f"{getattr(ex, 'workers', None)} workers; "
                           f"{len(pids - {os.getpid()})} worker processes")


def _pid_of(_):
    time.sleep(0.2)
    return os.getpid()


def pool(profile):
    """Three jobs in a process pool, each result saved as it arrives; the first takes no
    time, the other two a minute (test_cli stops it with Ctrl-C in between)."""
    def save(job, index):
        artifacts.ensure(f"jobs/{index}.json", {"job": index}, lambda: {"job": index},
                         profile=cache_dir(profile))

    run_jobs(_job, [(0, 0.0), (1, 60.0), (2, 60.0)], workers=2, start_method="fork",
             on_result=save, progress=False)
    return StageOutput([], "ran 3 jobs")


def settings(profile):
    """Says two of the settings it was given (test_cli checks `--set` reaches the stages)."""
    return StageOutput([], f"n_hill={profile.experiments.n_hill!r} "
                           f"beta={profile.planner.beta!r}")

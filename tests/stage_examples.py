"""Tiny stages used by tests/test_cli.py to exercise `dgt reproduce`."""

import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

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
    time, the other two a minute (test_cli stops it with Ctrl-C in between). Workers
    forked, or started as $POOL_START_METHOD says."""
    def save(job, index):
        artifacts.ensure(f"jobs/{index}.json", {"job": index}, lambda: {"job": index},
                         profile=cache_dir(profile))

    run_jobs(_job, [(0, 0.0), (1, 60.0), (2, 60.0)], workers=2,
             start_method=os.environ.get("POOL_START_METHOD", "fork"),
             on_result=save, progress=False)
    return StageOutput([], "ran 3 jobs")


def settings(profile):
    """Says two of the settings it was given (test_cli checks `--set` reaches the stages)."""
    return StageOutput([], f"n_hill={profile.experiments.n_hill!r} "
                           f"beta={profile.planner.beta!r}")


POOL_RUN = textwrap.dedent("""
    import sys
    from dgt_lib.stages import registry
    from tests import stage_examples
    registry.STAGES[:] = [registry.Stage("pool", stage_examples.pool, "jobs"),
                          registry.Stage("first", stage_examples.first, "next")]
    from dgt_lib.app.cli import main
    sys.exit(main(["reproduce", "--profile", "smoke"]))
""")
"""`dgt reproduce` of the stages ``pool`` (minute-long jobs in worker processes) then
``first``, as a script for a child process."""


def start_pool_run(data_dir: Path, preexec_fn, start_method: str = "fork"
                   ) -> subprocess.Popen:
    """:data:`POOL_RUN` in a child process of its own session (``preexec_fn`` sets its
    signal dispositions), returned once the pool's first job is saved, so a signal sent
    then stops a stage that has kept something."""
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "DGT_DATA_DIR": str(data_dir), "PYTHONPATH": str(root),
           "POOL_START_METHOD": start_method}
    proc = subprocess.Popen([sys.executable, "-c", POOL_RUN], cwd=root, env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True, preexec_fn=preexec_fn)
    saved = data_dir / "smoke" / "seed-0" / "jobs" / "0.json.meta.json"
    deadline = time.monotonic() + 60
    while not saved.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert saved.exists(), proc.stderr.read() if proc.poll() is not None else "not saved"
    return proc

"""Faults from outside the kit (docs/reliability.md): a run stopped by SIGTERM (``kill``,
a batch scheduler, a container stopping) as Ctrl-C stops it; a parent killed outright; a
data directory missing, read-only or full; two runs on one data directory; a renderer that
cannot work; a cluster that gives up; a file that is not what its name says."""

import contextlib
import errno
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from dgt_lib.app.cli import main
from dgt_lib.core import artifacts
from dgt_lib.core.executors import run_jobs
from dgt_lib.stages import registry
from dgt_lib.stages.paths import cache_dir
from tests import stage_examples

ROOT = Path(__file__).resolve().parents[1]


def _default_signals() -> None:
    """The child starts as a terminal's program would, whatever this shell ignores."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _group_alive(pgid: int) -> list[int]:
    """The running processes of process group ``pgid`` (a zombie left for init is not)."""
    alive = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == pgid and fields[0] != "Z":
            alive.append(int(stat.parent.name))
    return alive


@pytest.mark.parametrize("target", ["process", "group"])
def test_sigterm_stops_a_pool_stage_in_seconds_keeps_its_results_and_exits_143(
        tmp_path, target):
    """SIGTERM to ``dgt reproduce`` alone (``kill PID``) or to its whole process group,
    workers included (a batch scheduler): it stops within seconds, says what it kept in
    one line, keeps the finished job, runs no later stage and exits with 143, the status
    of a process SIGTERM ended."""
    proc = stage_examples.start_pool_run(tmp_path, _default_signals)
    t0 = time.monotonic()
    if target == "group":
        os.killpg(proc.pid, signal.SIGTERM)
    else:
        os.kill(proc.pid, signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 143 and time.monotonic() - t0 < 15, err
    assert "Traceback" not in out + err
    assert [line for line in err.splitlines() if "terminated" in line] == [
        "dgt: terminated in seed 0 · pool. Kept: the earlier stages' outputs; what it had "
        "finished. Rerun `dgt reproduce --profile smoke` to resume."]
    assert (tmp_path / "smoke" / "seed-0" / "jobs" / "0.json").exists()
    assert not (tmp_path / "smoke" / "seed-0" / "example.json").exists()  # "first" never ran
    deadline = time.monotonic() + 10  # and no worker is left running its minute-long job
    while _group_alive(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _group_alive(proc.pid) == []


def test_sigterm_outside_a_command_keeps_its_usual_meaning():
    """The handler is only installed while a command runs, and not where SIGTERM is
    ignored on purpose."""
    from dgt_lib.core.faults import Terminated, interrupted_status, sigterm_as_interrupt

    before = signal.getsignal(signal.SIGTERM)
    with sigterm_as_interrupt(), pytest.raises(Terminated):
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)  # the handler raises here, long before this ends
    assert signal.getsignal(signal.SIGTERM) == before
    assert interrupted_status(Terminated()) == 143
    assert interrupted_status(KeyboardInterrupt()) == 130
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    try:
        with sigterm_as_interrupt():
            assert signal.getsignal(signal.SIGTERM) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGTERM, before)


def test_a_worker_forked_under_the_handler_dies_of_sigterm_without_a_traceback():
    """A pool worker forked while ``dgt`` has SIGTERM as Ctrl-C, and signalled before its
    initializer restores the default (a batch scheduler signals the whole group at once),
    ends as SIGTERM ends a process: no ``Terminated`` traceback from inside multiprocessing."""
    from dgt_lib.core.faults import sigterm_as_interrupt

    read_end, write_end = os.pipe()
    with sigterm_as_interrupt():
        pid = os.fork()
        if pid == 0:  # the child: what a worker does before init_worker
            os.dup2(write_end, 2)
            try:
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(5)
            finally:
                os._exit(3)  # reached only if the handler raised or returned
        os.close(write_end)
        _, status = os.waitpid(pid, 0)
    stderr = os.read(read_end, 65536).decode()
    os.close(read_end)
    assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGTERM, status
    assert "Traceback" not in stderr


# ---------------------------------------------------------------- the data directory

MADE = textwrap.dedent("""
    import os, sys, time
    from dgt_lib.core import artifacts
    from dgt_lib.stages import registry
    from dgt_lib.stages.paths import cache_dir

    def build():
        with open(os.environ["BUILDS"], "a") as f:  # outside the data directory
            f.write(f"{os.getpid()}\\n")
        time.sleep(float(os.environ.get("BUILD_S", "0")))
        return {"n": 1}

    def made(profile):
        artifacts.ensure("made.json", {"v": 1}, build, profile=cache_dir(profile))
        return registry.StageOutput([], "made")

    registry.STAGES[:] = [registry.Stage("made", made, "one artifact", "what it made")]
    from dgt_lib.app.cli import main
    sys.exit(main(["reproduce", "--profile", "smoke"]))
""")
"""`dgt reproduce` of one stage that builds one artifact, noting each build in $BUILDS
(after $BUILD_S seconds), as a script for a child process."""


def _start_made(data_dir: Path, builds: Path, prefix: list[str] = (), build_s: float = 0.0
                ) -> subprocess.Popen:
    env = {**os.environ, "DGT_DATA_DIR": str(data_dir), "PYTHONPATH": str(ROOT),
           "BUILDS": str(builds), "BUILD_S": str(build_s)}
    return subprocess.Popen([*prefix, sys.executable, "-c", MADE], cwd=ROOT, env=env,
                            text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def _builds(builds: Path) -> list[str]:
    return builds.read_text().split() if builds.exists() else []


@contextlib.contextmanager
def read_only(path: Path):
    """Yields the command prefix under which a child sees ``path`` read-only. For a user:
    ``path``'s directories lose their write permission (restored after). Root ignores
    permissions, so for root: a read-only bind mount of ``path`` in a mount namespace of
    the child's own (``unshare -m``; skipped where that is not allowed)."""
    if os.geteuid() != 0:
        dirs = [path, *(p for p in path.rglob("*") if p.is_dir())]
        modes = {d: d.stat().st_mode for d in dirs}
        for d in dirs:
            d.chmod(0o555)
        try:
            yield []
        finally:
            for d, mode in modes.items():
                d.chmod(mode)
        return
    prefix = ["unshare", "-m", "sh", "-c", 'mount --bind -o ro "$0" "$0" && exec "$@"',
              str(path)]
    try:
        probe = subprocess.run([*prefix, "sh", "-c", f"! touch {path}/.probe"],
                               capture_output=True, timeout=30)
    except FileNotFoundError:
        probe = None
    if probe is None or probe.returncode != 0:
        pytest.skip("as root, a read-only directory needs a mount namespace (unshare -m), "
                    "which this machine does not allow")
    yield prefix


def test_a_fully_cached_run_on_a_read_only_data_directory_succeeds(tmp_path):
    """Nothing needs writing, so nothing is asked of the directory: the run loads its
    artifact and says once that the stage times could not be recorded."""
    data, builds = tmp_path / "data", tmp_path / "builds"
    first = _start_made(data, builds)
    assert first.wait(60) == 0, first.stderr.read()
    with read_only(data) as prefix:
        proc = _start_made(data, builds, prefix)
        out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert "Traceback" not in err and "made" in out
    assert _builds(builds) == [str(first.pid)]  # loaded, not built again
    notes = [line for line in err.splitlines() if "stage times not recorded" in line]
    assert len(notes) == 1 and "Read-only file system" in notes[0]


def test_a_run_that_must_build_on_a_read_only_data_directory_stops_before_building(
        tmp_path):
    """One line naming what could not be written and why, the usual "Kept" line, exit
    status 1 — and the build never started."""
    data, builds = tmp_path / "data", tmp_path / "builds"
    data.mkdir()
    with read_only(data) as prefix:
        proc = _start_made(data, builds, prefix)
        out, err = proc.communicate(timeout=60)
    assert proc.returncode == 1 and "Traceback" not in out + err
    lines = [line for line in err.splitlines() if line.startswith(("dgt:", "Kept:"))]
    made = data / "smoke" / "seed-0" / "made.json"
    assert lines == [
        f"dgt: error in seed 0 · made: cannot write {made} (read-only file system): set "
        "DGT_DATA_DIR to a directory you can write (a fully cached run writes nothing)",
        "Kept: the earlier stages' outputs; what it made. Rerun `dgt reproduce --profile "
        "smoke` to resume."]
    assert _builds(builds) == []


@pytest.fixture
def made_stage(monkeypatch, tmp_path):
    """`dgt reproduce`'s stages: one that builds ``made.json`` (``builds`` counts them)."""
    builds = []

    def made(profile):
        artifacts.ensure("made.json", {"v": 1}, lambda: builds.append(1) or {"n": 1},
                         profile=cache_dir(profile))
        return registry.StageOutput([], "made")

    monkeypatch.setattr(registry, "STAGES", [registry.Stage("made", made, "one artifact")])
    return builds


def test_a_missing_data_directory_is_made(tmp_path, monkeypatch, made_stage):
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path / "new" / "data"))
    assert main(["reproduce", "--profile", "smoke"]) == 0
    assert (tmp_path / "new" / "data" / "smoke" / "seed-0" / "made.json").exists()


@pytest.mark.parametrize("where,says", [
    ("file", "is not a directory"),
    ("file/data", "cannot create the data directory"),
])
def test_a_data_directory_that_cannot_be_one_is_one_line_before_any_work(
        tmp_path, monkeypatch, capsys, made_stage, where, says):
    (tmp_path / "file").write_text("not a directory")
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path / where))
    assert main(["reproduce", "--profile", "smoke"]) == 1
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and err.startswith("dgt: error: ")
    assert says in err and str(tmp_path / where) in err and "DGT_DATA_DIR" in err
    assert made_stage == []


def test_a_disk_full_mid_stage_keeps_what_was_saved_and_says_what_space_it_needed(
        tmp_path, monkeypatch, capsys):
    """ENOSPC while the second of two artifacts is written: the first stays valid, the
    second leaves nothing behind, one line says where, the free space and about how much
    the file needed, then what was kept; exit status 1, no traceback."""
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    savez, calls = np.savez, []

    def savez_until_full(f, **arrays):
        calls.append(1)
        if len(calls) > 1:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        savez(f, **arrays)

    def fill(profile):
        for name in ("a", "b"):
            artifacts.ensure(f"{name}.npz", {"n": name}, lambda: {"x": np.zeros(10**6)},
                             profile=cache_dir(profile))
        return registry.StageOutput([], "filled")

    monkeypatch.setattr(registry, "STAGES", [registry.Stage("fill", fill, "two arrays",
                                                            "every array written")])
    monkeypatch.setattr(np, "savez", savez_until_full)
    assert main(["reproduce", "--profile", "smoke"]) == 1
    err = capsys.readouterr().err
    seed_dir = tmp_path / "smoke" / "seed-0"
    first, second = err.splitlines()[-2:]
    assert first.startswith(f"dgt: error in seed 0 · fill: no space left to write "
                            f"{seed_dir / 'b.npz'} (")
    assert "free, about 8.0 MB needed): free some space" in first
    assert second == ("Kept: the earlier stages' outputs; every array written. Rerun "
                      "`dgt reproduce --profile smoke` to resume.")
    assert "Traceback" not in err
    assert artifacts.is_fresh("a.npz", {"n": "a"}, profile="smoke/seed-0")
    assert sorted(p.name for p in seed_dir.iterdir() if p.suffix != ".lock") == [
        "a.npz", "a.npz.meta.json"]


# ---------------------------------------------------------------- concurrent runs

def test_two_runs_on_one_data_directory_build_an_artifact_once(tmp_path):
    """The second run waits for the first one's build and loads its result; neither calls
    it corrupt nor rebuilds it."""
    data, builds = tmp_path / "data", tmp_path / "builds"
    first = _start_made(data, builds, build_s=3.0)
    deadline = time.monotonic() + 60
    while not _builds(builds) and time.monotonic() < deadline:  # the first is building
        time.sleep(0.05)
    second = _start_made(data, builds)
    outs = [p.communicate(timeout=90) for p in (first, second)]
    assert [first.returncode, second.returncode] == [0, 0], outs
    assert _builds(builds) == [str(first.pid)]
    said = "".join(out + err for out, err in outs)
    assert "rebuilding" not in said and "corrupt" not in said and "Traceback" not in said


# ---------------------------------------------------------------- renderer, input files

@pytest.mark.parametrize("value,missing", [("bogus", None), ("osmesa", "OSMesa")])
def test_a_renderer_that_cannot_work_is_one_sentence_before_any_work(
        monkeypatch, capsys, tmp_path, made_stage, value, missing):
    from dgt_lib.world import opengl

    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    monkeypatch.setenv("MUJOCO_GL", value)
    found = opengl._library_found
    monkeypatch.setattr(opengl, "_library_found", lambda name: name != missing and found(name))
    assert main(["reproduce", "--profile", "smoke"]) == 1
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(f"dgt: error: MUJOCO_GL='{value}' cannot render")
    assert "egl" in err[0] and "osmesa (software: needs libOSMesa)" in err[0]
    assert "glfw (needs a display)" in err[0]
    assert made_stage == [] and not (tmp_path / "smoke").exists()


def test_a_text_file_named_npy_is_said_to_be_no_heightmap(tmp_path, capsys):
    fake = tmp_path / "terrain.npy"
    fake.write_text("x,y,z\n0,0,1\n")
    assert main(["plan", "--world", str(fake), "--vehicle", "jeep", "--start", "1,1,0",
                 "--goal", "5,5", "--profile", "smoke"]) == 2
    err = capsys.readouterr().err
    assert err == f"dgt plan: error: {fake} is not a NumPy heightmap: a .npy file starts " \
                  "with NumPy's header (np.save writes one); this one does not\n"


# ---------------------------------------------------------------- a parent killed outright

def _children(pid: int) -> set[int]:
    """The processes whose parent is ``pid`` (read from /proc)."""
    out = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.add(int(stat.parent.name))
    return out


def _running(pid: int) -> bool:
    """Whether ``pid`` runs (not gone, not a zombie waiting to be reaped)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
@pytest.mark.parametrize("start_method", ["fork", "spawn"])
def test_pool_workers_and_the_resource_tracker_end_when_the_parent_is_killed(
        tmp_path, start_method):
    """SIGKILL (or the out-of-memory killer) gives the parent no chance to stop its pool:
    the workers, each in a minute-long job, notice their parent is gone and exit within
    seconds, and multiprocessing's resource tracker (spawned workers) follows them."""
    proc = stage_examples.start_pool_run(tmp_path, _default_signals, start_method)
    children = _children(proc.pid)  # the two workers, and a resource tracker if spawned
    assert len(children) == (3 if start_method == "spawn" else 2), children
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(10)
    deadline = time.monotonic() + 10
    while any(map(_running, children)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert [pid for pid in children if _running(pid)] == []


# ---------------------------------------------------------------- a cluster that gives up

def test_a_dask_cluster_giving_up_on_a_job_is_one_sentence_and_what_was_kept(
        tmp_path, monkeypatch, capsys):
    """A job whose worker dies every time (here at once: no failure allowed) ends in
    Dask's KilledWorker: one sentence on what happened and what to do, the "Kept" line,
    exit status 1, no traceback."""
    pytest.importorskip("distributed")
    import dask

    def dies(profile):
        run_jobs(os._exit, [(1,)], progress=False)
        return registry.StageOutput([], "survived")

    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    monkeypatch.setattr(registry, "STAGES", [registry.Stage("dies", dies, "a dying job")])
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        status = main(["reproduce", "--profile", "smoke", "--executor", "dask",
                       "--workers", "1"])
    err = capsys.readouterr().err
    assert status == 1 and "Traceback" not in err
    said = [line for line in err.splitlines() if line.startswith(("dgt:", "Kept:"))]
    assert said == [
        "dgt: error in seed 0 · dies: the Dask cluster gave up on a job after the workers "
        "running it died (distributed.scheduler.allowed-failures times): usually out of "
        "memory — give the workers more memory or run fewer per machine (--workers)",
        "Kept: the earlier stages' outputs; what it had finished. Rerun `dgt reproduce "
        "--profile smoke --executor dask --workers 1` to resume."]


def test_a_cluster_giving_up_on_a_job_is_recognised_by_name_and_by_subclass():
    from dgt_lib.core import faults

    gave_up = type("KilledWorker", (RuntimeError,), {"__module__": "distributed.scheduler"})
    subclass = type("Detailed", (gave_up,), {"__module__": "distributed.scheduler"})
    assert "memory" in faults.explain(gave_up("worker died"))
    assert faults.explain(subclass("worker died")) == faults.explain(gave_up("x"))
    assert faults.explain(RuntimeError("worker died")) is None


PLAN_WITH_A_GIVEN_TAU_S = textwrap.dedent("""
    import sys
    from dgt_lib.stages import costmaps
    costmaps.ensure_tau_s = lambda profile=None: 0.6  # not from the hill's and ridge's surveys
    from dgt_lib.app.cli import main
    sys.exit(main(sys.argv[1:]))
""")
"""`dgt` with τ_s given: a plan on a tiny world then needs its survey alone (seconds, where
the hill's and ridge's surveys that select τ_s take minutes)."""


def test_dgt_plan_on_a_read_only_data_directory_with_everything_cached_prints_the_plan(
        tmp_path):
    """The plan needs nothing written: it is printed, with one line saying where the figure
    and recording could not be written and why; exit status 0."""
    data = tmp_path / "data"
    heights = np.zeros((80, 120), np.float32)
    heights[30:50, 55:65] = 3.0
    np.save(tmp_path / "tiny.npy", heights)
    command = [sys.executable, "-c", PLAN_WITH_A_GIVEN_TAU_S, "plan", "--world",
               str(tmp_path / "tiny.npy"), "--vehicle", "jeep", "--start", "8,16,0",
               "--goal", "40,16", "--method", "binary", "--profile", "smoke"]
    env = {**os.environ, "DGT_DATA_DIR": str(data), "PYTHONPATH": str(ROOT)}
    first = subprocess.run(command, env=env, cwd=ROOT, capture_output=True, text=True,
                           timeout=600)
    assert first.returncode == 0, first.stderr
    for plans in (data / "smoke" / "seed-0" / "plans").iterdir():
        plans.unlink()  # so that this run would have to write them again
    with read_only(data) as prefix:
        proc = subprocess.run([*prefix, *command], env=env, cwd=ROOT, capture_output=True,
                              text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr and "found: length" in proc.stdout
    said = [line for line in proc.stdout.splitlines() if "not written" in line]
    assert len(said) == 1 and said[0].startswith(
        "  figure and rerun recording not written: cannot write "
        f"{data / 'smoke' / 'seed-0' / 'plans'}/tiny_jeep_binary_8.0_16.0_0deg_to_40.0_16.0_")
    assert "(read-only file system)" in said[0]


def test_a_report_that_cannot_be_written_is_one_line_and_the_run_goes_on(tmp_path, capsys):
    """A fully cached run rewrites its tables and figures: on a read-only or full disk that
    is one line, never the end of a run whose results are all stored."""
    import errno as errno_

    from dgt_lib.core.faults import report_writes

    with report_writes("results/accuracy.md"):
        raise OSError(errno_.EROFS, "Read-only file system", str(tmp_path / "accuracy.md"))
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "results/accuracy.md not written" in err
    assert "Read-only file system" in err and "cached results stand" in err
    with pytest.raises(OSError), report_writes("x"):  # other errors are not hidden
        raise OSError(errno_.EISDIR, "Is a directory")

"""Running bigger: the same episodes and trials on a Dask cluster as in the process
pool, no finished work lost when a worker dies, one place that opens and closes executors,
and the device switch (docs/scale-out.md)."""

import os
import signal
from concurrent.futures.process import BrokenProcessPool
from dataclasses import replace

import numpy as np
import pytest

from dgt_lib.core import artifacts
from dgt_lib.core.config import ExecutionConfig, get_profile
from dgt_lib.core.executors import (
    SerialExecutor,
    current_executor,
    make_executor,
    run_jobs,
    use_executor,
)
from dgt_lib.evaluation.queries import hill_queries
from dgt_lib.evaluation.trials import run_trials, trial_tasks
from dgt_lib.perception.episodes import load_episode
from dgt_lib.stages.collect import collect_episodes, episode_relpath
from dgt_lib.stages.experiments import trial_maps
from dgt_lib.stages.paths import cache_dir
from dgt_lib.stages.paths import data_dir as seed_dir
from dgt_lib.world.terrain import get_world

pytest.importorskip("distributed")  # in the dev extra: `make test` runs these


def tiny_profile(episodes=(1, 0, 1, 0), duration_s=3.0):
    """The smoke profile with a few short episodes and two pool / cluster workers."""
    p = get_profile("smoke")
    return p.with_(workers=2, collect=replace(p.collect, episodes=episodes,
                                              episode_duration_s=duration_s))


@pytest.fixture
def data_dir(tmp_path, monkeypatch):
    """A private artifact directory; local clusters started later inherit it."""
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    return tmp_path


def _square(x):
    return x * x


def _fails_on_zero(x):
    if x == 0:
        raise RuntimeError("job 0 failed")
    return x


def _worker_state(_):
    import torch

    return (os.environ.get("OMP_NUM_THREADS"), os.environ.get("LP_NUM_THREADS"),
            os.environ.get("MUJOCO_GL"), torch.get_num_threads(),
            os.environ.get(artifacts.DATA_ENV_VAR))


# ----------------------------------------------------------------------------- same results


def _episodes_equal(a, b, prof, dir_a, dir_b):
    """The same episodes, and the same stored artifacts (BEV statistics included)."""
    assert [(e.vehicle, e.index) for e in a] == [(e.vehicle, e.index) for e in b]
    for ep in a:
        rel = f"{cache_dir(prof)}/{episode_relpath(ep.vehicle, ep.index)}"
        x = load_episode(dir_a / rel, with_bev=True).to_arrays()
        y = load_episode(dir_b / rel, with_bev=True).to_arrays()
        assert sorted(x) == sorted(y) and any(k.startswith("bev_") for k in x)
        for k in x:
            np.testing.assert_array_equal(x[k], y[k], err_msg=k)


def _trials_equal(a, b):
    assert [r.task for r in a] == [r.task for r in b]
    for x, y in zip(a, b, strict=True):
        assert x.outcome == y.outcome and x.route == y.route
        assert x.expansions == y.expansions and x.plan_cost == y.plan_cost
        for field in ("path", "trajectory", "speed"):
            np.testing.assert_array_equal(getattr(x, field), getattr(y, field))


def test_pool_workers_record_the_episodes_this_process_records(data_dir):
    """The pool's workers render with one llvmpipe thread (``LP_NUM_THREADS=1``), this
    process with the settings it started with (Mesa reads them at its first OpenGL
    context; unset, a render thread per core): the frames, so the stored episodes and
    their BEV statistics, are the same to the bit."""
    prof = tiny_profile()
    episodes = {}
    for name, executor in (("serial", SerialExecutor()), ("pool", None)):
        (data_dir / name).mkdir()
        os.environ[artifacts.DATA_ENV_VAR] = str(data_dir / name)
        episodes[name] = collect_episodes(prof, executor=executor, progress=False)
    _episodes_equal(episodes["serial"], episodes["pool"], prof, data_dir / "serial",
                    data_dir / "pool")


def test_a_local_cluster_gives_the_same_episodes_and_trials_as_the_process_pool(data_dir):
    """Same seeds → the same per-task results, whichever executor ran them: episodes
    through the profile's configuration (a cluster opened for the call), trials through
    one cluster for a block (what `dgt reproduce --executor` does)."""
    prof = tiny_profile()
    (data_dir / "pool").mkdir()
    os.environ[artifacts.DATA_ENV_VAR] = str(data_dir / "pool")
    pooled = collect_episodes(prof, progress=False)
    os.environ[artifacts.DATA_ENV_VAR] = str(data_dir / "dask")
    on_cluster = collect_episodes(prof.with_(execution=ExecutionConfig("dask")), progress=False)
    _episodes_equal(pooled, on_cluster, prof, data_dir / "pool", data_dir / "dask")
    assert (seed_dir(prof) / episode_relpath("jeep", 0)).exists()  # saved by this process

    hill = get_world("hill", prof)
    queries = hill_queries(hill, 2, prof.experiments, prof.seed)
    tasks = trial_tasks("experiment1", "hill", "carla_cola", queries, ["binary"], prof)
    trial_maps("hill", "binary", "carla_cola", prof)  # built here; the workers read it
    pooled = run_trials(tasks, trial_maps, workers=2, progress=False)
    with use_executor("dask", workers=2) as ex:
        assert current_executor() is ex and ex.workers == 2
        clustered = run_trials(tasks, trial_maps, workers=2, progress=False)
    assert current_executor() is None
    _trials_equal(pooled, clustered)


def test_cluster_workers_get_one_thread_headless_mujoco_and_the_data_directory(data_dir):
    with make_executor("dask", workers=2) as ex:
        states = set(run_jobs(_worker_state, [(i,) for i in range(4)], executor=ex,
                              progress=False).values())
    assert states == {("1", "1", "egl", 1, str(data_dir))}


# ----------------------------------------------------------------------------- dying workers


def test_results_that_finish_with_a_failed_job_are_kept():
    """A job that fails (or a worker that died under it) does not take the results that
    finished at the same time with it: they reach on_result before the error is raised."""
    kept = []
    with pytest.raises(RuntimeError, match="job 0 failed"):
        run_jobs(_fails_on_zero, [(0,), (1,), (2,)], executor=SerialExecutor(),
                 max_in_flight=3, progress=False, on_result=lambda job, r: kept.append(r))
    assert kept == [1, 2]


def _kill_after_first(kill, seen):
    def on_episode(ep):
        seen.append((ep.vehicle, ep.index))
        if len(seen) == 1:
            kill()
    return on_episode


def test_a_dask_worker_killed_mid_episode_loses_no_finished_episode(data_dir):
    """Dask reruns the killed worker's episode elsewhere; what was saved stays as it was
    and a rerun computes nothing."""
    prof = tiny_profile(episodes=(2, 1, 1, 0))
    seen = []
    with make_executor("dask", workers=2) as ex:
        def kill_a_busy_worker():
            processing = ex.client.processing()
            busy = [w for w, keys in processing.items() if keys] or list(processing)
            pid = ex.client.run(os.getpid, workers=busy[:1])[busy[0]]
            os.kill(pid, signal.SIGKILL)

        episodes = collect_episodes(prof, executor=ex, progress=False,
                                    on_episode=_kill_after_first(kill_a_busy_worker, seen))
    assert sorted(seen) == sorted((e.vehicle, e.index) for e in episodes) and len(seen) == 4
    first = seed_dir(prof) / episode_relpath(*seen[0])
    mtime = first.stat().st_mtime_ns
    again = []
    collect_episodes(prof, progress=False, on_episode=again.append)
    assert again == [] and first.stat().st_mtime_ns == mtime


def test_a_killed_pool_worker_stops_the_run_and_the_rerun_resumes(data_dir):
    """The process pool cannot rerun a dead worker's job: the run stops
    (BrokenProcessPool), and the rerun computes only what was not saved. One job in flight,
    so the worker dies between jobs: killed while it sends a result (an episode is larger
    than a pipe holds), it would leave the pool waiting for the rest of the message."""
    prof = tiny_profile(episodes=(2, 1, 1, 0))
    seen = []
    with pytest.raises(BrokenProcessPool), make_executor("process", workers=2) as ex:
        def kill_a_worker():
            os.kill(next(iter(ex._processes)), signal.SIGKILL)

        collect_episodes(prof, executor=ex, progress=False, max_in_flight=1,
                         on_episode=_kill_after_first(kill_a_worker, seen))
    saved = {(v, i) for v, i in [("jeep", 0), ("jeep", 1), ("vw_van", 0), ("mercedes_van", 0)]
             if (seed_dir(prof) / episode_relpath(v, i)).exists()}
    assert set(seen) == saved and len(saved) < 4
    rerun = []
    episodes = collect_episodes(prof, progress=False,
                                on_episode=lambda ep: rerun.append((ep.vehicle, ep.index)))
    assert set(rerun) | saved == {(e.vehicle, e.index) for e in episodes}
    assert not set(rerun) & saved


# ----------------------------------------------------------------------------- the one place


def test_make_executor_closes_what_it_opened_and_never_a_users_cluster(data_dir):
    from distributed import Client, LocalCluster

    with make_executor("dask", workers=1) as ex:
        assert run_jobs(_square, [(3,)], executor=ex, progress=False) == {(3,): 9}
        cluster = ex.client.cluster
    assert ex.client.status == "closed" and cluster.status.name == "closed"

    with LocalCluster(n_workers=1, threads_per_worker=1, dashboard_address=":0") as users:
        with pytest.raises(KeyboardInterrupt), make_executor(
                "dask", address=users.scheduler_address) as ex:
            assert ex.workers == 1
            raise KeyboardInterrupt  # Ctrl-C: our client goes, the user's cluster stays
        assert ex.client.status == "closed"
        with Client(users) as client:
            assert client.submit(_square, 4).result() == 16


def test_run_jobs_opens_the_profiles_executor_only_when_it_has_none():
    assert run_jobs(_square, [], backend="dask", progress=False) == {}  # no jobs, no cluster
    with pytest.raises(ValueError, match="valid: process, dask$"):
        run_jobs(_square, [(1,)], backend="spark", progress=False)
    with pytest.raises(ValueError, match="no address"):
        with make_executor("process", address="tcp://x:1"):
            pass
    with use_executor("process") as ex:  # the default changes nothing
        assert ex is None and current_executor() is None


def test_execution_settings_change_neither_the_profile_nor_a_cache_key():
    """Trials journaled by one executor are the same tasks for another: a run resumes
    wherever it goes on."""
    p = get_profile("smoke")
    q = p.with_(workers=8, execution=ExecutionConfig("dask", "tcp://h:8786", "cpu"))
    assert p == q and hash(p) == hash(q)
    [query] = hill_queries(get_world("hill", p), 1, p.experiments, 0)
    assert trial_tasks("e", "hill", "jeep", [query], ["dgt"], p) == \
        trial_tasks("e", "hill", "jeep", [query], ["dgt"], q)
    with pytest.raises(ValueError, match="unknown executor"):
        ExecutionConfig("spark")
    with pytest.raises(ValueError, match="unknown device"):
        ExecutionConfig(device="tpu")
    with pytest.raises(ValueError, match="address needs"):
        ExecutionConfig("process", "tcp://h:8786")


# ----------------------------------------------------------------------------- devices


def test_device_auto_picks_cuda_when_torch_sees_it(monkeypatch):
    import torch

    from dgt_lib.learning.training import resolve_device

    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    assert resolve_device("auto").type == "cuda" and resolve_device(None).type == "cuda"
    assert resolve_device("cpu").type == "cpu"
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert resolve_device("auto").type == "cpu"
    with pytest.raises(ValueError, match="sees no CUDA GPU"):
        resolve_device("cuda")


def test_ensure_model_trains_on_the_profiles_device(data_dir, monkeypatch):
    import torch

    from dgt_lib.learning import run
    from dgt_lib.stages import train

    asked = []

    def fake_train_model(dataset, cfg, *, device, **kwargs):
        asked.append(torch.device(device))
        raise KeyboardInterrupt  # enough: nothing is trained or cached

    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)  # as on a GPU machine
    monkeypatch.setattr(run, "train_model", fake_train_model)
    monkeypatch.setattr(train, "dataset_fingerprint", lambda ds: "ds")
    prof = get_profile("smoke")
    for device in ("cpu", "auto"):
        with pytest.raises(KeyboardInterrupt):
            train.ensure_model(prof.with_(execution=ExecutionConfig(device=device)), None)
    assert [d.type for d in asked] == ["cpu", "cuda"]

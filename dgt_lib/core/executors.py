"""Running independent jobs in parallel: one harness for collection episodes, ground-truth
samples and closed-loop trials (docs/ARCHITECTURE.md → Scale).

Any :class:`concurrent.futures.Executor` works — a process pool of spawned workers by default
(:func:`default_executor`), a :class:`SerialExecutor` for one worker, or a Dask executor.
:func:`run_jobs` submits at most ``max_in_flight`` jobs at a time, hands every finished result
to ``on_result`` *in this process* as soon as it is there (so the caller can save or journal
it: an interruption loses only the jobs in flight) and shows a progress bar with an ETA.
Results do not depend on the executor.

The choice of executor is made here only: :func:`make_executor` opens one of
:data:`~dgt_lib.core.config.EXECUTORS` — ``"process"`` or ``"dask"`` (``distributed``) —
on a local cluster or an existing one (``address``), and closes what it opened;
:func:`use_executor` makes it the one every :func:`run_jobs` without an executor uses
(``dgt reproduce --executor``).

Example::

    results = run_jobs(square, [(1,), (2,), (3,)], workers=2, desc="squares")
    with make_executor("dask", workers=2) as ex:          # a local Dask cluster
        results = run_jobs(square, [(1,), (2,), (3,)], executor=ex)
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Hashable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Executor, Future, ProcessPoolExecutor, wait
from typing import Any

from dgt_lib.core.artifacts import DATA_ENV_VAR
from dgt_lib.core.config import ENV_VAR as PROFILE_ENV_VAR
from dgt_lib.core.config import EXECUTORS

THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
               "NUMEXPR_NUM_THREADS", "VECLIB_MAXIMUM_THREADS",
               "LP_NUM_THREADS")  # the last: Mesa llvmpipe's render threads
"""Thread-count variables set to 1 in workers (the processes already fill the cores)."""


def limit_threads() -> None:
    """One BLAS/OpenMP/torch/llvmpipe thread per worker (``dgt_lib`` itself sets
    ``MUJOCO_GL=egl`` on import, in workers too)."""
    for var in THREAD_VARS:
        os.environ[var] = "1"
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(1)


class SerialExecutor(Executor):
    """An :class:`~concurrent.futures.Executor` that runs each job in this process
    when it is submitted (``workers <= 1``, debugging, tests)."""

    def submit(self, fn, /, *args, **kwargs) -> Future:
        future: Future = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # noqa: BLE001 - delivered through the future
            future.set_exception(exc)
        return future


def init_worker() -> None:
    """Initializer of the kit's pool workers: one thread (:func:`limit_threads`), and SIGINT
    ignored — a terminal's Ctrl-C reaches every process of the group, and the parent, not each
    worker, decides (:func:`run_jobs` stops the pool). SIGTERM is the default's again (a
    forked worker inherits :func:`~dgt_lib.core.faults.sigterm_as_interrupt`): it is how the
    parent terminates a worker. A worker whose parent is gone (SIGKILL, the out-of-memory
    killer) ends itself (:func:`exit_with_parent`)."""
    limit_threads()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # blocked by WorkerPool
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    exit_with_parent()


class WorkerPool(ProcessPoolExecutor):
    """The kit's process pool: a worker starts with SIGINT blocked, so that a Ctrl-C in
    the instant it is forked does not land in its start-up code (a traceback on the
    terminal) — :func:`init_worker` ignores SIGINT, then unblocks it. In the parent the
    signal waits the few milliseconds of the start, then arrives as usual."""

    def _spawn_process(self) -> None:  # CPython's hook that starts one worker
        old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            super()._spawn_process()
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)


PARENT_POLL_S = 0.5  # how often a pool worker checks that its parent is alive [s]


def exit_with_parent(poll_s: float = PARENT_POLL_S) -> threading.Thread:
    """End this process within ``poll_s`` of its parent's death (a daemon thread watches
    ``os.getppid()``: an orphan gets another parent); else a worker outlives a parent
    killed by SIGKILL, finishing a job nobody will receive. Not ``prctl``'s death signal:
    it follows the thread that started the worker, not the process."""
    parent = getattr(multiprocessing.parent_process(), "pid", None) or os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(poll_s)
        os._exit(1)  # no cleanup to run: the results had nobody to go to

    thread = threading.Thread(target=watch, name="dgt-exit-with-parent", daemon=True)
    thread.start()
    return thread


def stop_workers(executor: Executor) -> None:
    """Shut ``executor`` down without waiting for the jobs it is running: pending jobs
    are cancelled and the processes of a :class:`ProcessPoolExecutor` terminated (what
    Ctrl-C needs: stop within seconds, not when the longest job ends). Its manager thread
    is joined too: left running, it closes its wake-up pipe while the interpreter's exit
    hook writes to it (a "Bad file descriptor" traceback at exit, CPython 3.11)."""
    processes = dict(getattr(executor, "_processes", None) or {})  # shutdown clears these
    manager = getattr(executor, "_executor_manager_thread", None)
    executor.shutdown(wait=False, cancel_futures=True)
    for proc in processes.values():
        if proc.is_alive():
            proc.terminate()
    for waited in [*processes.values(), *([manager] if manager else [])]:
        waited.join(timeout=5)


@contextlib.contextmanager
def worker_environment() -> Iterator[None]:
    """Environment inherited by spawned workers: single-threaded BLAS."""
    saved = {k: os.environ.get(k) for k in THREAD_VARS}
    os.environ.update(dict.fromkeys(THREAD_VARS, "1"))
    try:
        yield
    finally:
        os.environ.update({k: v for k, v in saved.items() if v is not None})
        for k in (k for k, v in saved.items() if v is None):
            os.environ.pop(k, None)


def worker_env() -> dict[str, str]:
    """Environment variables of the cluster workers :func:`make_executor` starts: one
    thread each (:data:`THREAD_VARS`), headless MuJoCo, and this process's data directory
    and profile, so that a worker reads the same artifact cache."""
    env = {var: "1" for var in THREAD_VARS}
    env["MUJOCO_GL"] = os.environ.get("MUJOCO_GL", "egl")
    for var in (DATA_ENV_VAR, PROFILE_ENV_VAR):
        if os.environ.get(var):
            env[var] = os.environ[var]
    return env


def call_in_worker(fn: Callable[..., Any], *args: Any) -> Any:
    """What a Dask worker runs for one job: the set-up a pool worker gets from its
    initializer (headless MuJoCo, :func:`limit_threads`), then ``fn(*args)``. Workers of
    a cluster we did not start (``address``) get it too."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    limit_threads()
    return fn(*args)


class DaskExecutor(Executor):
    """Jobs on a Dask cluster through ``client``: each job runs :func:`call_in_worker`,
    as a fresh task (``pure=False``: never merged with an identical earlier one). A worker
    that dies mid-job has its job rerun on another (Dask's ``allowed-failures``).
    ``workers`` is the cluster's thread count (what :func:`run_jobs` keeps busy)."""

    def __init__(self, client: Any) -> None:
        self.client = client
        self._inner = client.get_executor(pure=False)

    @property
    def workers(self) -> int:
        return max(1, sum(self.client.nthreads().values()))

    def submit(self, fn, /, *args, **kwargs) -> Future:
        if kwargs:
            raise TypeError("DaskExecutor.submit takes positional arguments only")
        return self._inner.submit(call_in_worker, fn, *args)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """Stop taking jobs; ``cancel_futures`` (or ``wait=False``) cancels the jobs not
        finished. The client and the cluster stay open (:func:`make_executor` owns them)."""
        self._inner.shutdown(wait=wait and not cancel_futures)


@contextlib.contextmanager
def _dask(address: str | None, workers: int) -> Iterator[Executor]:
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ImportError("executor 'dask' needs the 'distributed' package: "
                          "pip install 'dgt-kit[dask]' (or pip install distributed)") from None
    cluster = None
    if address is None:  # our own cluster: single-threaded worker processes, quiet logs
        # no dashboard, and its HTTP server on a free port: never "8787 already in use"
        cluster = LocalCluster(n_workers=max(1, workers), threads_per_worker=1,
                               processes=True, dashboard_address=None,
                               scheduler_kwargs={"dashboard_address": ":0"},
                               silence_logs=logging.ERROR, env=worker_env())
    try:
        client = Client(cluster if cluster is not None else address)
        try:
            ex = DaskExecutor(client)
            try:
                yield ex
            except BaseException:
                ex.shutdown(wait=False, cancel_futures=True)  # our jobs, not the cluster
                raise
        finally:
            client.close()  # ours; a cluster at `address` is the user's and stays up
    finally:
        if cluster is not None:
            cluster.close()


@contextlib.contextmanager
def make_executor(kind: str = "process", *, address: str | None = None, workers: int = 2,
                  start_method: str = "spawn") -> Iterator[Executor]:
    """An executor of ``kind`` for the ``with`` block, closed after it — the one place
    the kit chooses how jobs run.

    ``"process"``: :func:`default_executor` (``workers`` processes, ``start_method``; a
    :class:`SerialExecutor` for ``workers <= 1``). ``"dask"``: a :class:`DaskExecutor` on
    the scheduler at ``address``, or on a ``LocalCluster`` of ``workers`` single-threaded
    worker processes started here (needs ``distributed``). Local workers get
    :func:`worker_env`.

    On an exception or Ctrl-C in the block, the jobs not finished are cancelled and the
    pool's processes terminated (:func:`stop_workers`); the Dask client opened here is
    closed, and a local cluster started here is stopped — a cluster at ``address`` is
    never stopped.
    """
    if kind not in EXECUTORS:
        raise ValueError(f"unknown executor {kind!r}; valid: {', '.join(EXECUTORS)}")
    if kind == "dask":
        with _dask(address, workers) as ex:
            yield ex
        return
    if address is not None:
        raise ValueError("executor 'process' runs on this machine: it takes no address")
    ex = default_executor(workers, start_method)
    try:
        yield ex
    except BaseException:
        stop_workers(ex)
        raise
    ex.shutdown(wait=True)


_CURRENT: list[Executor] = []
"""The executors of the enclosing :func:`use_executor` blocks, innermost last."""


def current_executor() -> Executor | None:
    """The executor of the innermost :func:`use_executor` block, or None."""
    return _CURRENT[-1] if _CURRENT else None


@contextlib.contextmanager
def use_executor(kind: str = "process", *, address: str | None = None,
                 workers: int = 2) -> Iterator[Executor | None]:
    """Run every :func:`run_jobs` of the block that is given no executor through one
    executor of ``kind`` (:func:`make_executor`), opened once for the block — one local
    Dask cluster for a whole ``dgt reproduce``. ``"process"`` changes nothing
    (each :func:`run_jobs` keeps its own pool, forked for trials) and yields None."""
    if kind == "process":
        if address is not None:
            raise ValueError("executor 'process' runs on this machine: it takes no address")
        yield None
        return
    with make_executor(kind, address=address, workers=workers) as ex:
        _CURRENT.append(ex)
        try:
            yield ex
        finally:
            _CURRENT.remove(ex)


def default_executor(workers: int, start_method: str = "spawn") -> Executor:
    """A process pool of ``workers`` processes (each one thread), or a
    :class:`SerialExecutor` for ``workers <= 1``.

    start_method: ``"spawn"`` (a fresh interpreter: safe with OpenGL contexts and torch
    threads in the parent) or ``"fork"`` (starts in milliseconds; for jobs whose parent
    holds no GL context, e.g. closed-loop trials, each of which builds its own)."""
    if workers <= 1:
        return SerialExecutor()
    return WorkerPool(max_workers=workers, mp_context=multiprocessing.get_context(
        start_method), initializer=init_worker)


def run_jobs(
    fn: Callable[..., Any],
    jobs: Sequence[tuple],
    *,
    executor: Executor | None = None,
    workers: int = 2,
    start_method: str = "spawn",
    backend: str = "process",
    address: str | None = None,
    max_in_flight: int | None = None,
    on_result: Callable[[tuple, Any], None] | None = None,
    progress: bool = True,
    desc: str = "jobs",
    unit: str = "job",
    initial: int = 0,
    total: int | None = None,
    postfix: Callable[[], str] | None = None,
) -> dict[Hashable, Any]:
    """Run ``fn(*job)`` for every job; returns ``{job: result}``.

    executor: any Executor; default the one of the enclosing :func:`use_executor` block,
    else one :func:`make_executor` opens for this call — ``backend`` (``"process"``:
    ``workers`` processes started by ``start_method``; ``"dask"``: a local
    cluster of ``workers``, or the one at ``address``) — and closes afterwards. On an
    exception or Ctrl-C (KeyboardInterrupt) the jobs not yet finished are cancelled and
    the exception re-raised; an executor opened here is stopped at once (the pool's
    workers terminated, :func:`stop_workers`), so Ctrl-C stops within seconds, and every
    result already handed to ``on_result`` stays with the caller; so does every result
    that finished together with a failed job. At most
    ``max_in_flight`` jobs are submitted at once (default 2 per worker — the cluster's
    workers for a Dask executor —, 1 for a :class:`SerialExecutor`), in ``jobs``
    order. ``on_result(job, result)`` runs in this
    process for each finished job, in ``jobs`` order among those finishing together.
    The bar starts at ``initial`` of ``total`` (default ``initial + len(jobs)``), for
    work done earlier; ``postfix()`` is shown beside it after every job.
    """
    from tqdm.auto import tqdm

    out: dict[Hashable, Any] = {}
    if not jobs:
        return out
    with contextlib.ExitStack() as scope:
        ex = executor if executor is not None else current_executor()
        if ex is None:
            ex = scope.enter_context(make_executor(backend, address=address, workers=workers,
                                                   start_method=start_method))
        serial = isinstance(ex, SerialExecutor)
        n_workers = getattr(ex, "workers", workers)
        limit = max_in_flight or (1 if serial else max(2, 2 * n_workers))
        bar = tqdm(total=total if total is not None else initial + len(jobs), initial=initial,
                   desc=desc, unit=unit, disable=not progress)

        def finished(job: tuple, result: Any) -> None:
            out[job] = result
            if on_result is not None:
                on_result(job, result)
            bar.update(1)
            if postfix is not None:
                bar.set_postfix_str(postfix())

        try:
            with worker_environment():
                _submit_all(ex, fn, jobs, limit, finished)
        finally:
            bar.close()
    return out


def _submit_all(ex: Executor, fn: Callable[..., Any], jobs: Sequence[tuple], limit: int,
                finished: Callable[[tuple, Any], None]) -> None:
    """Submit ``fn(*job)`` for ``jobs`` in order, at most ``limit`` in flight, and call
    ``finished(job, result)`` for each, in ``jobs`` order among those finishing together; a
    failed job's exception is raised once the others finished with it are handed over. On
    any exception the jobs not yet finished are cancelled."""
    order = {job: k for k, job in enumerate(jobs)}
    queue = iter(jobs)
    pending: dict[Future, tuple] = {}

    def fill() -> None:
        while len(pending) < limit:
            job = next(queue, None)
            if job is None:
                return
            pending[ex.submit(fn, *job)] = job

    try:
        fill()
        while pending:
            done, _ = wait(list(pending), return_when=FIRST_COMPLETED)
            failed: BaseException | None = None
            for fut in sorted(done, key=lambda f: order[pending[f]]):
                job = pending.pop(fut)
                if fut.exception() is not None:  # keep the others' results first
                    failed = failed or fut.exception()
                    continue
                finished(job, fut.result())
            if failed is not None:
                raise failed
            fill()
    except BaseException:
        for fut in pending:
            fut.cancel()
        raise

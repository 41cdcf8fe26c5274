"""Running independent jobs in parallel: one harness for collection episodes, ground-truth
samples and closed-loop trials (docs/ARCHITECTURE.md → Scale).

Any :class:`concurrent.futures.Executor` works — a process pool of spawned workers by
default (:func:`default_executor`), a :class:`SerialExecutor` for one worker, or a
Dask/Ray executor passed in. :func:`run_jobs` submits at most ``max_in_flight`` jobs at a
time, hands every finished result to ``on_result`` *in this process* as soon as it is
there (so the caller can save or journal it: an interruption loses only the jobs in
flight) and shows a progress bar with an ETA. Results do not depend on the executor.

Example::

    results = run_jobs(square, [(1,), (2,), (3,)], workers=2, desc="squares")
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import sys
from collections.abc import Callable, Hashable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Executor, Future, ProcessPoolExecutor, wait
from typing import Any

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
    """Initializer of the kit's pool workers: one thread (:func:`limit_threads`), and
    SIGINT ignored — a terminal's Ctrl-C reaches every process of the group, and the
    parent, not each worker, decides what happens (:func:`run_jobs` stops the pool)."""
    limit_threads()
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def stop_workers(executor: Executor) -> None:
    """Shut ``executor`` down without waiting for the jobs it is running: pending jobs
    are cancelled and the processes of a :class:`ProcessPoolExecutor` terminated (what
    Ctrl-C needs: stop within seconds, not when the longest job ends)."""
    processes = dict(getattr(executor, "_processes", None) or {})  # shutdown clears it
    executor.shutdown(wait=False, cancel_futures=True)
    for proc in processes.values():
        if proc.is_alive():
            proc.terminate()
    for proc in processes.values():
        proc.join(timeout=5)


@contextlib.contextmanager
def worker_environment() -> Iterator[None]:
    """Environment inherited by spawned workers: single-threaded BLAS."""
    saved = {k: os.environ.get(k) for k in THREAD_VARS}
    for var in THREAD_VARS:
        os.environ[var] = "1"
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def default_executor(workers: int, start_method: str = "spawn") -> Executor:
    """A process pool of ``workers`` processes (each one thread), or a
    :class:`SerialExecutor` for ``workers <= 1``.

    start_method: ``"spawn"`` (a fresh interpreter: safe with OpenGL contexts and torch
    threads in the parent) or ``"fork"`` (starts in milliseconds; for jobs whose parent
    holds no GL context, e.g. closed-loop trials, each of which builds its own)."""
    if workers <= 1:
        return SerialExecutor()
    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context(
        start_method), initializer=init_worker)


def run_jobs(
    fn: Callable[..., Any],
    jobs: Sequence[tuple],
    *,
    executor: Executor | None = None,
    workers: int = 2,
    start_method: str = "spawn",
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

    executor: any Executor; default :func:`default_executor` (``workers``,
    ``start_method``), shut down afterwards. On an exception or Ctrl-C
    (KeyboardInterrupt) the jobs not yet finished are cancelled and the exception
    re-raised; the default pool's workers are terminated at once (:func:`stop_workers`),
    so Ctrl-C stops within seconds, and every result already handed to ``on_result``
    stays with the caller. At most
    ``max_in_flight`` jobs are submitted at once (default 2 per worker, 1 for a
    :class:`SerialExecutor`), in ``jobs`` order. ``on_result(job, result)`` runs in this
    process for each finished job, in ``jobs`` order among those finishing together.
    The bar starts at ``initial`` of ``total`` (default ``initial + len(jobs)``), for
    work done earlier; ``postfix()`` is shown beside it after every job.
    """
    from tqdm.auto import tqdm

    out: dict[Hashable, Any] = {}
    if not jobs:
        return out
    own = executor is None
    ex = default_executor(workers, start_method) if own else executor
    serial = isinstance(ex, SerialExecutor)
    limit = max_in_flight or (1 if serial else max(2, 2 * workers))
    order = {job: k for k, job in enumerate(jobs)}
    queue = iter(jobs)
    pending: dict[Future, tuple] = {}
    bar = tqdm(total=total if total is not None else initial + len(jobs), initial=initial,
               desc=desc, unit=unit, disable=not progress)

    def fill() -> None:
        while len(pending) < limit:
            job = next(queue, None)
            if job is None:
                return
            pending[ex.submit(fn, *job)] = job

    try:
        with worker_environment():
            fill()
            while pending:
                finished, _ = wait(list(pending), return_when=FIRST_COMPLETED)
                for fut in sorted(finished, key=lambda f: order[pending[f]]):
                    job = pending.pop(fut)
                    out[job] = result = fut.result()
                    if on_result is not None:
                        on_result(job, result)
                    bar.update(1)
                    if postfix is not None:
                        bar.set_postfix_str(postfix())
                fill()
    except BaseException:
        for fut in pending:
            fut.cancel()
        if own:
            stop_workers(ex)
        raise
    finally:
        bar.close()
    if own:
        ex.shutdown(wait=True)
    return out

"""The parallel-jobs harness: what Ctrl-C does to a pool of worker processes."""

import multiprocessing
import os
import signal
import threading
import time
from concurrent.futures import ProcessPoolExecutor

import pytest

from dgt_lib.core.executors import WorkerPool, default_executor, run_jobs, stop_workers


def _sleep_then_return(index: int, seconds: float, pid_dir: str) -> int:
    (open(os.path.join(pid_dir, str(os.getpid())), "w")).close()
    time.sleep(seconds)
    return index


def _ctrl_c_in_the_terminal() -> str:
    """A terminal's Ctrl-C sends SIGINT to every process of the group, workers included."""
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(0.2)
    return "still working"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_ctrl_c_stops_the_pool_within_seconds_and_keeps_finished_results(tmp_path):
    kept = []

    def save_then_ctrl_c(job, result):
        kept.append(result)  # what the caller saved (an episode, a journaled trial)
        raise KeyboardInterrupt  # the user presses Ctrl-C while the others still run

    jobs = [(0, 0.0, str(tmp_path))] + [(i, 60.0, str(tmp_path)) for i in (1, 2, 3)]
    t0 = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        run_jobs(_sleep_then_return, jobs, workers=2, start_method="fork",
                 on_result=save_then_ctrl_c, progress=False)
    assert time.perf_counter() - t0 < 15  # not when the 60 s jobs end
    assert kept == [0]
    workers = [int(p.name) for p in tmp_path.iterdir()]
    assert workers and not any(_alive(pid) for pid in workers)


def test_workers_leave_a_terminal_ctrl_c_to_the_parent():
    """A worker does not die with a KeyboardInterrupt (and its traceback) of its own."""
    try:
        out = run_jobs(_ctrl_c_in_the_terminal, [()], workers=2, start_method="fork",
                       progress=False)
    except KeyboardInterrupt:
        pytest.fail("the worker's Ctrl-C came back as the job's exception")
    assert out == {(): "still working"}


def test_a_stopped_pool_leaves_no_thread_to_race_the_interpreters_exit(tmp_path):
    """After Ctrl-C or SIGTERM stops a pool, its manager thread has ended too: a thread
    still closing the pool's pipes while the interpreter exits printed a "Bad file
    descriptor" traceback after a clean stop."""
    before = set(threading.enumerate())
    pool = ProcessPoolExecutor(2)
    futures = [pool.submit(_sleep_then_return, i, 60.0, str(tmp_path)) for i in range(3)]
    while len(list(tmp_path.iterdir())) < 2:  # both workers are inside a job
        time.sleep(0.05)
    t0 = time.perf_counter()
    stop_workers(pool)
    assert time.perf_counter() - t0 < 15
    assert [t for t in threading.enumerate() if t not in before and t.is_alive()] == []
    assert all(f.done() for f in futures)


def _sigint_state() -> tuple[bool, bool]:
    """(blocked, ignored) of SIGINT in this process, from /proc."""
    status = dict(line.split(":\t", 1) for line in
                  open("/proc/self/status").read().splitlines() if ":\t" in line)
    bit = 1 << (signal.SIGINT - 1)
    return bool(int(status["SigBlk"], 16) & bit), bool(int(status["SigIgn"], 16) & bit)


_AT_START: tuple[bool, bool] | None = None


def _record_at_start() -> None:
    global _AT_START
    _AT_START = _sigint_state()


def _at_start() -> tuple[bool, bool] | None:
    return _AT_START


def test_a_pool_worker_starts_with_ctrl_c_blocked_so_it_never_lands_in_its_start_up():
    """A terminal's Ctrl-C that arrives while a worker is forked must not interrupt the
    worker's start-up code (a traceback on the terminal): SIGINT is blocked from the fork
    to the initializer, and the parent's own mask is as it was."""
    with WorkerPool(1, mp_context=multiprocessing.get_context("fork"),
                    initializer=_record_at_start) as ex:
        blocked, _ = ex.submit(_at_start).result()
    assert blocked
    assert signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, set())


def test_the_kit_s_pool_workers_ignore_ctrl_c_and_leave_it_unblocked_for_their_children():
    with default_executor(2, "fork") as ex:
        assert ex.submit(_sigint_state).result() == (False, True)


"""Faults from outside the kit: a run stopped by SIGTERM (``kill``, a batch scheduler, a
container stopping) as Ctrl-C stops it (docs/reliability.md)."""

import os
import signal
import time
from pathlib import Path

import pytest

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
    from dgt_lib.core.executors import Terminated, interrupted_status, sigterm_as_interrupt

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

import os
import signal
import subprocess
import sys
import textwrap
import time
from dataclasses import replace
from pathlib import Path

import pytest

from dgt_lib.app.cli import build_parser, main
from dgt_lib.stages import registry as pipeline
from tests import stage_examples

ROOT = Path(__file__).resolve().parents[1]


def test_reproduce_runs_and_summarises(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("DGT_DATA_DIR", str(tmp_path))
    monkeypatch.setattr(pipeline, "STAGES", [])
    assert main(["reproduce", "--profile", "smoke"]) == 0
    out = capsys.readouterr().out
    assert "profile 'smoke'" in out and str(tmp_path / "smoke") in out
    assert "no stages yet" in out


@pytest.fixture
def two_stages(tmp_path, monkeypatch):
    """The data directory in ``tmp_path`` and a pipeline of two tiny stages (one writes a
    file, the other reads it: ``tests/stage_examples.py``)."""
    monkeypatch.setenv("DGT_DATA_DIR", str(tmp_path))
    monkeypatch.setattr(pipeline, "STAGES", [
        pipeline.Stage("first", stage_examples.first, "writes a file"),
        pipeline.Stage("second", stage_examples.second, "reads it")])


def test_reproduce_runs_registered_stages_in_order_with_summary(capsys, tmp_path, two_stages):
    assert main(["reproduce", "--profile", "smoke", "--stages", "second", "first"]) == 0
    out = capsys.readouterr().out
    assert out.index("first") < out.index("second")  # pipeline order, not argument order
    assert "wrote 1 file" in out and str(tmp_path / "smoke" / "seed-0" / "example.json") in out


def test_reproduce_runs_every_stage_for_every_seed_each_in_its_own_directory(
        capsys, tmp_path, two_stages):
    assert main(["reproduce", "--profile", "smoke", "--seeds", "3"]) == 0
    out = capsys.readouterr().out
    assert "seed(s) 0, 1, 2" in out
    for seed in (0, 1, 2):
        assert (tmp_path / "smoke" / f"seed-{seed}" / "example.json").exists()
        assert f"read n=1 of seed {seed}" in out
    assert main(["reproduce", "--profile", "smoke", "--seeds", "0"]) == 2
    assert "--seeds must be ≥ 1" in capsys.readouterr().err


def test_every_stage_s_wall_time_is_kept_per_seed_and_run_and_survives_an_interrupt(
        capsys, tmp_path, monkeypatch, two_stages):
    import importlib.util

    from dgt_lib.stages.timings import read_stage_times

    spec = importlib.util.spec_from_file_location(
        "stage_times", Path(__file__).resolve().parents[1] / "benchmarks" / "stage_times.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    last_run, stage_time_table = bench.last_run, bench.stage_time_table

    assert main(["reproduce", "--profile", "smoke", "--seeds", "2"]) == 0
    assert str(tmp_path / "smoke" / "stage_times.jsonl") in capsys.readouterr().out
    first = read_stage_times("smoke")
    assert [(r["seed"], r["stage"]) for r in first] == [
        (0, "first"), (0, "second"), (1, "first"), (1, "second")]
    assert all(r["seconds"] >= 0 and r["workers"] == 2 for r in first)
    assert len({r["run"] for r in first}) == 1

    def interrupted(profile):
        raise KeyboardInterrupt

    monkeypatch.setattr(pipeline, "STAGES", [pipeline.STAGES[0],
                                             replace(pipeline.STAGES[1], run=interrupted)])
    assert main(["reproduce", "--profile", "smoke"]) == 130
    records = read_stage_times("smoke")
    assert len(records) == 5  # the finished stage of the interrupted run is kept
    assert [(r["seed"], r["stage"]) for r in last_run(records)] == [(0, "first")]
    table = stage_time_table(first)
    assert table.count("**total**") == 2 and "| 1 | second |" in table


def test_unknown_stage_and_profile_are_clear_errors(capsys, monkeypatch):
    monkeypatch.setattr(pipeline, "STAGES", [pipeline.Stage("a", stage_examples.first, "d")])
    assert main(["reproduce", "--stages", "nope"]) == 2
    assert "unknown stage(s) nope; valid stages: a" in capsys.readouterr().err
    monkeypatch.setenv("DGT_PROFILE", "huge")
    assert main(["reproduce"]) == 2
    assert "valid profiles: smoke, demo, paper" in capsys.readouterr().err


def test_python_dash_m_entry_point():
    done = subprocess.run([sys.executable, "-m", "dgt_lib", "--help"], capture_output=True,
                          text=True, check=True)
    assert "reproduce" in done.stdout


@pytest.mark.parametrize("interrupted", [s.name for s in pipeline.STAGES])
def test_ctrl_c_in_any_stage_stops_the_run_with_one_line_and_status_130(
        interrupted, capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("DGT_DATA_DIR", str(tmp_path))
    ran = []

    def fake(name):
        def stage(profile):
            ran.append(name)
            if name == interrupted:
                raise KeyboardInterrupt
            return pipeline.StageOutput([], f"{name} done")
        return stage

    monkeypatch.setattr(pipeline, "STAGES", [replace(s, run=fake(s.name), report=False)
                                             for s in pipeline.STAGES])
    try:
        assert main(["reproduce", "--profile", "smoke"]) == 130
    except KeyboardInterrupt:
        pytest.fail("Ctrl-C escaped `dgt reproduce` (a traceback for the user)")
    names = [s.name for s in pipeline.STAGES]
    assert ran == names[: names.index(interrupted) + 1]  # no later stage ran
    out, err = capsys.readouterr()
    said = [line for line in (out + err).splitlines() if "interrupted" in line]
    kept = pipeline.STAGES[names.index(interrupted)].kept
    assert said == [f"dgt: interrupted in seed 0 · {interrupted}. Kept: the earlier stages' "
                    f"outputs; {kept}. Rerun `dgt reproduce --profile smoke` to resume."]
    assert "Traceback" not in out + err and "Summary" not in out


def sigint_as_in_a_terminal() -> None:
    """In the child, before it starts: SIGINT's default disposition, as a terminal's
    program has it. A shell starts a background job (``nohup make test &``) with SIGINT
    ignored and a child inherits that, so without this the Ctrl-C tests would send a
    signal the run never sees."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_in_a_terminal_stops_a_pool_stage_in_seconds_and_keeps_its_results(tmp_path):
    """The real thing: SIGINT to the whole process group (as a terminal sends it) while a
    stage runs jobs in worker processes."""
    proc = stage_examples.start_pool_run(tmp_path, sigint_as_in_a_terminal)
    t0 = time.monotonic()
    os.killpg(proc.pid, signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and time.monotonic() - t0 < 15
    assert "Traceback" not in out + err
    assert [line for line in err.splitlines() if "interrupted" in line] == [
        "dgt: interrupted in seed 0 · pool. Kept: the earlier stages' outputs; what it had "
        "finished. Rerun `dgt reproduce --profile smoke` to resume."]
    assert (tmp_path / "smoke" / "seed-0" / "jobs" / "0.json").exists()
    assert not (tmp_path / "smoke" / "seed-0" / "example.json").exists()  # "first" never ran


def _alive(pid: int) -> bool:
    """Running (a zombie left for init to reap is not)."""
    try:
        os.kill(pid, 0)
        stat = Path(f"/proc/{pid}/stat").read_text()
    except (ProcessLookupError, FileNotFoundError):
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def test_reproduce_runs_its_jobs_on_the_executor_it_is_given(capsys, tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    from dgt_lib.core.executors import current_executor

    monkeypatch.setenv("DGT_DATA_DIR", str(tmp_path))
    monkeypatch.setattr(pipeline, "STAGES", [
        pipeline.Stage("jobs", stage_examples.executor, "four quick jobs")])
    assert main(["reproduce", "--profile", "smoke", "--executor", "dask", "--workers", "2"]) == 0
    out = capsys.readouterr().out
    assert "jobs: dask on a local cluster of 2 workers" in out
    assert "executor DaskExecutor with 2 workers; 2 worker processes" in out
    assert current_executor() is None  # closed with the run
    assert main(["reproduce", "--profile", "smoke"]) == 0  # the default: its own pools
    assert "executor None with None workers; 2 worker processes" in capsys.readouterr().out


def test_execution_options_that_cannot_work_are_one_line_errors(capsys, monkeypatch):
    import torch

    monkeypatch.setattr(pipeline, "STAGES", [])
    assert main(["reproduce", "--address", "tcp://h:8786"]) == 2
    assert "an address needs executor 'dask'" in capsys.readouterr().err
    assert main(["reproduce", "--workers", "0"]) == 2
    assert "--workers must be ≥ 1" in capsys.readouterr().err
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert main(["reproduce", "--device", "cuda"]) == 2
    assert "--device cuda" in capsys.readouterr().err
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "distributed" else real(name, *a))
    assert main(["reproduce", "--executor", "dask"]) == 2
    assert "pip install 'dgt-kit[dask]'" in capsys.readouterr().err
    for kind in ("ray", "spark"):
        with pytest.raises(SystemExit):
            main(["reproduce", "--executor", kind])
        assert "invalid choice" in capsys.readouterr().err


def test_ctrl_c_stops_a_cluster_run_in_seconds_and_stops_its_local_cluster(tmp_path):
    """SIGINT to the whole process group (the cluster's workers included) while jobs run on
    a local Dask cluster: exit 130 with the one line, the finished job kept, no worker
    process left."""
    pytest.importorskip("distributed")
    script = textwrap.dedent("""
        import sys
        from dgt_lib.stages import registry
        from tests import stage_examples
        registry.STAGES[:] = [registry.Stage("pool", stage_examples.pool, "jobs")]
        from dgt_lib.app.cli import main
        sys.exit(main(["reproduce", "--profile", "smoke", "--executor", "dask"]))
    """)
    env = {**os.environ, "DGT_DATA_DIR": str(tmp_path), "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-c", script], cwd=ROOT, env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True, preexec_fn=sigint_as_in_a_terminal)
    saved = tmp_path / "smoke" / "seed-0" / "jobs" / "0.json.meta.json"
    pids = tmp_path / "pids"
    deadline = time.monotonic() + 120
    while (not saved.exists() or len(list(pids.glob("*"))) < 2) and proc.poll() is None \
            and time.monotonic() < deadline:
        time.sleep(0.05)
    assert saved.exists()
    time.sleep(0.5)
    t0 = time.monotonic()
    os.killpg(proc.pid, signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and time.monotonic() - t0 < 15, err
    assert "Traceback" not in out + err
    assert [line for line in err.splitlines() if "interrupted" in line] == [
        "dgt: interrupted in seed 0 · pool. Kept: the earlier stages' outputs; what it had "
        "finished. Rerun `dgt reproduce --profile smoke --executor dask` to resume."]
    workers = [int(p.name) for p in pids.iterdir()]
    assert workers and proc.pid not in workers
    deadline = time.monotonic() + 10
    while any(_alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_alive(pid) for pid in workers)


def test_profile_names_follow_one_rule_on_the_command_line_and_in_the_environment(
        capsys, tmp_path, monkeypatch):
    """`DGT_PROFILE=Smoke` works, so `--profile Smoke` must too (case-insensitive both)."""
    monkeypatch.setenv("DGT_DATA_DIR", str(tmp_path))
    monkeypatch.setattr(pipeline, "STAGES", [])
    monkeypatch.setenv("DGT_PROFILE", "Smoke")
    assert main(["reproduce"]) == 0
    assert "profile 'smoke'" in capsys.readouterr().out
    monkeypatch.delenv("DGT_PROFILE")
    assert main(["reproduce", "--profile", "Smoke"]) == 0
    assert "profile 'smoke'" in capsys.readouterr().out
    args = build_parser().parse_args(["plan", "--world", "hill", "--vehicle", "jeep",
                                      "--start", "1,2,0", "--goal", "3,4", "--profile", "PAPER"])
    assert args.profile == "paper"
    with pytest.raises(SystemExit):
        main(["reproduce", "--profile", "huge"])
    assert "valid profiles: smoke, demo, paper" in capsys.readouterr().err


def test_set_changes_settings_for_every_stage_and_seed(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("DGT_DATA_DIR", str(tmp_path))
    monkeypatch.setattr(pipeline, "STAGES", [
        pipeline.Stage("settings", stage_examples.settings, "says its settings")])
    assert main(["reproduce", "--profile", "smoke", "--seeds", "2", "--set", "planner.beta=50",
                 "--set", "experiments.n_hill=10"]) == 0
    out = capsys.readouterr().out
    assert "profile 'smoke' with planner.beta=50.0, experiments.n_hill=10, seed(s) 0, 1" in out
    assert out.count("n_hill=10 beta=50.0") == 2  # typed: an int and a float, both seeds


@pytest.mark.parametrize("setting, message", [
    ("planner.bta=50", "unknown setting 'planner.bta'; valid planner settings: planner.step_m, "
                       "planner.beta"),
    ("planner.beta=fifty", "planner.beta expects a number (e.g. planner.beta=150.0), "
                           "got 'fifty'"),
    ("planner.beta", "a setting is NAME=VALUE"),
    # out of range: refused before any stage, not stored as a run of failed trials
    ("planner.beta=-5", "planner.beta=-5.0 is not allowed: planner.beta must be a finite "
                        "number ≥ 0"),
    ("train.epochs=0", "train.epochs=0 is not allowed: train.epochs must be an integer in "
                       "[1, 10,000]"),
    ("train.batch_size=-1", "train.batch_size=-1 is not allowed"),
    ("workers=0", "workers=0 is not allowed: workers must be an integer in [1, 256]"),
])
def test_a_bad_set_is_a_clear_error_before_anything_runs(capsys, tmp_path, monkeypatch,
                                                         setting, message):
    monkeypatch.setenv("DGT_DATA_DIR", str(tmp_path))
    monkeypatch.setattr(pipeline, "STAGES", [
        pipeline.Stage("first", stage_examples.first, "writes a file")])
    assert main(["reproduce", "--profile", "smoke", "--set", setting]) == 2
    assert f"dgt: error: {message}" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []  # nothing ran
    assert main(["plan", "--world", "hill", "--vehicle", "jeep", "--start", "1,2,0",
                 "--goal", "3,4", "--profile", "smoke", "--set", setting]) == 2
    assert f"dgt: error: {message}" in capsys.readouterr().err


def test_dgt_plan_takes_set_too(capsys, monkeypatch):
    import types

    import dgt_lib.app.plan_one

    seen = {}

    def fake_plan_query(world, vehicle, start, goal, *, profile, **kwargs):
        seen["profile"] = profile
        return types.SimpleNamespace(summary=lambda: "planned",
                                     plan=types.SimpleNamespace(success=True, failure=""))

    monkeypatch.setattr(dgt_lib.app.plan_one, "plan_query", fake_plan_query)
    assert main(["plan", "--world", "hill", "--vehicle", "jeep", "--start", "1,2,0", "--goal",
                 "3,4", "--profile", "smoke", "--set", "planner.beta=0",
                 "--set", "planner.heuristic=euclidean"]) == 0
    assert seen["profile"].planner.beta == 0.0
    assert seen["profile"].planner.heuristic == "euclidean"


def test_the_pipeline_bar_counts_stages_and_promises_no_time_left(capsys, tmp_path,
                                                                  monkeypatch):
    """The bar averaged over stages of very different cost ("3 s left" after collection):
    it shows how many stages ran and the time spent, no ETA and no rate."""
    monkeypatch.setenv("DGT_DATA_DIR", str(tmp_path))
    monkeypatch.setattr(pipeline, "STAGES", [
        pipeline.Stage("first", stage_examples.first, "writes a file"),
        pipeline.Stage("second", stage_examples.second, "reads it")])
    assert main(["reproduce", "--profile", "smoke"]) == 0
    bar = capsys.readouterr().err.replace("\r", "\n")
    assert "2/2 stages [" in bar
    assert "<" not in bar and "stage/s" not in bar and "s/stage" not in bar


def test_version_is_the_package_s(capsys):
    import dgt_lib

    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    assert capsys.readouterr().out == f"dgt {dgt_lib.__version__}\n"


def _subcommands() -> dict:
    import argparse

    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices


def test_every_help_text_is_plain_text_with_no_rst_markup():
    """`dgt --help` printed the module docstring's ``dgt`` literally; argparse shows help
    as it is written, so no double backticks and no :func:/:class: roles anywhere."""
    import re

    subcommands = _subcommands()
    assert {"reproduce", "stages", "settings", "plan"} <= set(subcommands)
    for name, text in [("dgt", build_parser().format_help()),
                       *((n, p.format_help()) for n, p in subcommands.items())]:
        assert "``" not in text, name
        assert not re.search(r":[a-z]+:`", text), name
        assert "dgt_lib." not in text, name  # no API names in the help


def test_plan_takes_only_the_four_vehicles(capsys):
    with pytest.raises(SystemExit):
        main(["plan", "--world", "hill", "--vehicle", "tank", "--start", "1,2,0",
              "--goal", "3,4"])
    err = capsys.readouterr().err
    assert "invalid choice: 'tank'" in err
    assert all(v in err for v in ("jeep", "vw_van", "mercedes_van", "carla_cola"))


def test_settings_lists_every_name_set_takes_with_its_type_value_and_allowed_range(capsys):
    import re
    from dataclasses import replace

    from dgt_lib.core.config import Profile, get_profile
    from dgt_lib.core.overrides import setting_names

    assert main(["settings", "--profile", "demo"]) == 0
    lines = capsys.readouterr().out.splitlines()
    cols = {c[0]: c[1:] for c in (re.split(r"\s{2,}", line.strip()) for line in lines[1:])}
    assert list(cols) == setting_names(Profile)  # every name, nothing else
    assert cols["planner.beta"][:2] == ["float", "150.0"]
    assert cols["costmap.stride"][:2] == ["tuple[int, int]", "4,2"]  # demo's, not (6, 3)
    assert cols["train.patience"][0].startswith("int | None")
    assert cols["costmap.n_headings"][2].startswith("an integer in [")  # its bound, shown
    # what it prints is what --set takes: typed back, every value gives demo itself
    demo = get_profile("demo")
    typed = {name: c[1] for name, c in cols.items()}
    assert replace(demo.with_overrides(typed), overrides=()) == demo
    assert main(["settings", "--profile", "smoke", "--set", "planner.beta=50"]) == 0
    out = capsys.readouterr().out
    assert "with planner.beta=50.0" in out.splitlines()[0]
    assert re.split(r"\s{2,}", next(line for line in out.splitlines()[1:]
                                    if line.split()[0] == "planner.beta").strip())[2] == "50.0"


def test_seed_runs_that_one_seed_alone(capsys, tmp_path, two_stages):
    assert main(["reproduce", "--profile", "demo", "--seed", "2"]) == 0
    out = capsys.readouterr().out
    assert "seed(s) 2," in out and "read n=1 of seed 2" in out
    assert [p.name for p in (tmp_path / "demo").iterdir() if p.is_dir()] == ["seed-2"]
    assert main(["reproduce", "--profile", "demo", "--seed", "-1"]) == 2
    assert "--seed must be ≥ 0" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["reproduce", "--seed", "2", "--seeds", "3"])
    assert "not allowed with argument" in capsys.readouterr().err


def test_one_seed_alone_leaves_the_pooled_results_as_they_are(capsys, tmp_path, monkeypatch):
    import dgt_lib.app.report

    monkeypatch.setenv("DGT_DATA_DIR", str(tmp_path))
    monkeypatch.setattr(pipeline, "STAGES", [
        pipeline.Stage("experiments", stage_examples.first, "stands in")])
    pooled = []
    monkeypatch.setattr(dgt_lib.app.report, "write_seeds_report",
                        lambda profile: pooled.append(profile.seed_profiles()) or tmp_path)
    assert main(["reproduce", "--profile", "smoke", "--seed", "1"]) == 0
    assert pooled == [] and "pooled results were left as they were" in capsys.readouterr().out
    assert main(["reproduce", "--profile", "smoke", "--seeds", "2"]) == 0
    assert [[p.seed for p in runs] for runs in pooled] == [[0, 1]]


@pytest.mark.parametrize("value", ["1e6", "0", "nan", "-1"])
def test_a_heightmap_resolution_no_machine_can_map_is_refused_by_the_parser(capsys, value):
    """--resolution 1e6 ended in "Unable to allocate 279 PiB" after the world was read."""
    with pytest.raises(SystemExit) as exit_:
        main(["costmap", "--world", "x.npy", "--vehicle", "jeep", f"--resolution={value}",
              "--out", "x.tif"])
    assert exit_.value.code == 2
    assert "metres per pixel in [0.001, 100]" in capsys.readouterr().err


def test_a_seed_s_results_are_shown_before_the_next_seed_runs(capsys, tmp_path, monkeypatch):
    """`make reproduce` runs several seeds for an hour or more: the first seed's claims and
    arrivals are printed as soon as its experiments are done, not only at the end."""
    import json

    import dgt_lib.app.report
    from dgt_lib.stages.output import StageOutput
    from dgt_lib.stages.paths import results_dir

    monkeypatch.setenv("DGT_DATA_DIR", str(tmp_path))
    monkeypatch.setattr(pipeline, "STAGES", [
        pipeline.Stage("experiments", stage_examples.first, "stands in", report=True)])

    def report_stage(name, profile, output):
        out = results_dir(profile)
        out.mkdir(parents=True, exist_ok=True)
        claims = {"hill_ascent_A": [3, 3, True], "ridge_smooth": [1, 2, False],
                  "ridge_jeep_sharp": [0, 0, False]}
        (out / "summary.json").write_text(json.dumps({"claims": claims}))
        (out / "README.md").write_text("# Results")
        return StageOutput([out / "README.md", out / "summary.json"],
                           f"experiment1: DGT-Map {profile.seed + 2}/3")

    monkeypatch.setattr(dgt_lib.app.report, "report_stage", report_stage)
    monkeypatch.setattr(dgt_lib.app.report, "write_seeds_report", lambda profile: tmp_path)
    assert main(["reproduce", "--profile", "smoke", "--seeds", "3"]) == 0
    out = capsys.readouterr().out
    first = out.index("── seed 0's results (seeds 1, 2 follow")
    assert out.index("── seed 0 · experiments") < first < out.index("── seed 1 · experiments")
    block = out[first:out.index("── seed 1 · experiments")]
    assert "✓ DGT-Map's carla_cola ascents planned by Route A: 3/3" in block
    assert "✗ DGT-Map's mercedes_van plans crossing at the smoothed section: 1/2" in block
    assert "jeep" not in block  # nothing to check in this seed: not listed
    assert "arrivals: experiment1: DGT-Map 2/3" in block
    assert str(tmp_path / "smoke" / "seed-0" / "results" / "README.md") in block
    assert "── seed 1's results (seed 2 follows" in out
    assert "── seed 2's results" not in out  # the last seed: the pooled report follows

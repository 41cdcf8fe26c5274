"""A study's record and the docs tables rendered from it: a table a study measured reaches
its page only through ``make docs``, with the run it rests on named beside it."""

import json
import sys
from pathlib import Path

import pytest

from dgt_lib.core import artifacts
from dgt_lib.records import documents, study

ROOT = Path(__file__).resolve().parent.parent
PROC = {"model": "Test CPU", "family": "1", "model_id": "2", "flags": ["avx2"], "cpus": 2}


def _record(**over) -> dict:
    rec = {"schema": 1, "commit": "abcdef0123456", "processor": PROC,
           "versions": {"python": "3"}, "date_utc": "2026-01-02T03:04:05Z",
           "study": "toy", "variant": "", "profile": "demo", "seeds": [0, 1, 2],
           "command": "python studies/toy.py --seeds 3 --publish",
           "tables": {"arrivals": study.table("arrivals", ["method", "k/n"],
                                              [["DGT-Map", "17/18"], ["Binary", "9/18"]])},
           "lists": {"failures": ["seed 0, ascent #0: immobilized"]}}
    return {**rec, **over}


def _page(root: Path, block: str) -> Path:
    page = root / "docs" / "toy.md"
    page.parent.mkdir(parents=True, exist_ok=True)
    page.write_text(f"# Toy\n\n<!-- generated: {block} -->\n<!-- end generated: {block} -->\n")
    return page


def test_a_study_table_renders_with_its_run_and_a_typed_number_is_caught(tmp_path):
    path = study.publish_study(_record(), tmp_path / "docs" / "runs" / "studies")
    assert path.name == "toy_demo_test-cpu-f1m2_2026-01-02.json"
    page = _page(tmp_path, f"study:{path.stem}/arrivals")
    text = documents.render_text(page.read_text(), {}, [], [], tmp_path, "docs/toy.md")
    assert "| DGT-Map | 17/18 |" in text and "| Binary | 9/18 |" in text
    assert ("*`demo`, seeds 0–2, Test CPU (family 1 model 2, AVX2), 2 CPUs, commit `abcdef0`: "
            "`python studies/toy.py --seeds 3 --publish`; record: "
            f"[{path.name}](runs/studies/{path.name})*") in text
    page.write_text(text.replace("17/18", "18/18"))  # a count changed by hand
    again = documents.render_text(page.read_text(), {}, [], [], tmp_path, "docs/toy.md")
    assert again == text and again != page.read_text()


def test_a_study_list_renders_and_an_unknown_part_or_record_is_named(tmp_path):
    path = study.publish_study(_record(), tmp_path / "docs" / "runs" / "studies")
    page = _page(tmp_path, f"study:{path.stem}/failures")
    text = documents.render_text(page.read_text(), {}, [], [], tmp_path, "docs/toy.md")
    assert "- seed 0, ascent #0: immobilized\n" in text
    with pytest.raises(ValueError, match="no table or list 'missing'"):
        study.render_block(f"study:{path.stem}/missing", page, tmp_path)
    with pytest.raises(FileNotFoundError, match="not published"):
        study.render_block("study:nobody_demo_x_2026-01-01/arrivals", page, tmp_path)


def test_a_study_s_variants_are_kept_apart_and_an_oversized_record_is_refused(tmp_path):
    plain = study.publish_study(_record(), tmp_path)
    hazard = study.publish_study(_record(variant="hazard"), tmp_path)
    assert plain != hazard and hazard.name.startswith("toy-hazard_demo_")
    assert study.record_name(_record(profile="smoke, demo")).startswith("toy_smoke-demo_test")
    rows = [["x" * 100, str(i)] for i in range(600)]
    with pytest.raises(ValueError, match="over 50000"):
        study.publish_study(_record(tables={"big": study.table("big", ["a", "b"], rows)}),
                            tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([plain.name, hazard.name])
    with pytest.raises(ValueError, match="3 cells under 2 columns"):
        study.table("t", ["a", "b"], [["1", "2", "3"]])


def test_the_study_runner_reads_seeds_and_data_dir_and_publishes(tmp_path, monkeypatch, capsys):
    monkeypatch.syspath_prepend(str(ROOT / "studies"))
    from runner import Study

    monkeypatch.setattr(study, "STUDIES", tmp_path / "studies")
    monkeypatch.delenv(artifacts.DATA_ENV_VAR, raising=False)
    toy = Study("toy", "A toy study.", stores=True)
    args = toy.parse(["--seed", "1", "--seed", "4", "--data-dir", str(tmp_path / "d"),
                      "--publish", "--stored"])
    assert toy.seeds == [1, 4] and args.profile == "demo"
    assert artifacts.data_root() == tmp_path / "d"
    record = toy.finish({"arrivals": study.table("arrivals", ["m", "k/n"], [["DGT-Map", "1/2"]])})
    assert record["command"] == ("python studies/toy.py --seed 1 --seed 4 --data-dir "
                                 f"{tmp_path / 'd'} --publish")
    written = json.loads(next((tmp_path / "studies").glob("toy_demo_*.json")).read_text())
    assert written["seeds"] == [1, 4] and written["tables"] == record["tables"]
    assert "| DGT-Map | 1/2 |" in capsys.readouterr().out
    default = Study("toy", None)
    with pytest.raises(SystemExit):  # a study that stores nothing has nothing to read back
        Study("toy", None).parse(["--stored"])
    default.parse([])
    assert default.seeds == [0, 1, 2] and not default.args.publish
    sys.modules.pop("runner", None)


def test_a_benchmark_s_record_names_the_load_it_was_timed_under(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    import argparse

    from publish import Benchmark

    monkeypatch.setattr(study, "STUDIES", tmp_path / "docs" / "runs" / "studies")
    loads = iter([(0.4, 0.3, 0.2), (1.7, 0.9, 0.5)])  # at the start, at the end
    monkeypatch.setattr("os.getloadavg", lambda: next(loads))
    monkeypatch.setattr(sys, "argv", ["bench_toy.py", "--repeats", "3", "--publish"])
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int)
    bench = Benchmark("bench_toy", parser)
    args = parser.parse_args()
    record = bench.finish({"rate": study.table("rate", ["case", "ms"], [["one", "1.5"]])},
                          args.publish)
    assert record["load"] == [0.4, 1.7] and record["profile"] == "" and record["seeds"] == []
    assert record["command"] == "python benchmarks/bench_toy.py --repeats 3 --publish"
    path = next((tmp_path / "docs" / "runs" / "studies").glob("bench_toy_*.json"))
    assert path.name.startswith("bench_toy_") and "__" not in path.name  # no profile part
    page = _page(tmp_path, f"study:{path.stem}/rate")
    text = documents.render_text(page.read_text(), {}, [], [], tmp_path, "docs/toy.md")
    assert "| one | 1.5 |" in text
    assert ", load average 0.4 → 1.7, commit `" in text and "no run's artifacts" not in text
    # a benchmark timing a profile's cache names the profile, not seeds it did not choose
    on_demo = study.caption({**record, "profile": "demo"}, "x.json")
    assert on_demo.startswith("*`demo`, ") and "seed" not in on_demo
    sys.modules.pop("publish", None)


def test_a_study_that_only_prints_has_no_publish_and_may_take_the_profile_s_seeds(
        monkeypatch, capsys):
    monkeypatch.syspath_prepend(str(ROOT / "studies"))
    from runner import Study

    from dgt_lib.core.config import get_profile

    quiet = Study("toy", None, profile="smoke", seeds=None, publishes=False)
    quiet.parse([])
    assert quiet.seeds == list(range(get_profile("smoke").seeds))
    quiet.parse(["--profile", "demo"])
    assert quiet.seeds == list(range(get_profile("demo").seeds))
    quiet.parse(["--seeds", "2"])
    assert quiet.seeds == [0, 1]
    with pytest.raises(SystemExit):
        quiet.parse(["--publish"])
    assert "unrecognized arguments: --publish" in capsys.readouterr().err
    sys.modules.pop("runner", None)


def test_a_study_stopped_by_sigterm_cleans_up_as_on_ctrl_c(tmp_path):
    """``kill`` (SIGTERM) stops a study as Ctrl-C does: its ``finally`` blocks run, so a
    temporary folder it made (a drive log's, for instance) does not stay behind."""
    import signal
    import subprocess

    script = (
        "import pathlib, shutil, sys, tempfile, time\n"
        f"sys.path.insert(0, {str(ROOT / 'studies')!r})\n"
        "from runner import Study\n"
        "Study('toy', None).parse([])\n"
        "work = pathlib.Path(tempfile.mkdtemp(dir=sys.argv[1]))\n"
        "try:\n"
        "    print('ready', flush=True)\n"
        "    time.sleep(60)\n"
        "finally:\n"
        "    shutil.rmtree(work)\n")
    proc = subprocess.Popen([sys.executable, "-c", script, str(tmp_path)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "ready"
    assert len(list(tmp_path.iterdir())) == 1
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode != 0
    assert list(tmp_path.iterdir()) == []  # the finally block ran
    assert err.strip() == ("studies/toy.py: terminated. Kept: nothing of this study; the "
                           "profile's cached artifacts are untouched.")  # one line, no traceback


def test_a_notebook_quoting_a_study_is_rendered_in_its_markdown_cell_alone(tmp_path):
    path = study.publish_study(_record(), tmp_path / "docs" / "runs" / "studies")
    block = f"study:{path.stem}/arrivals"
    code = {"cell_type": "code", "execution_count": None, "id": "c0", "metadata": {},
            "outputs": [], "source": [f"# <!-- generated: {block} --> in code stays\n"]}
    prose = {"cell_type": "markdown", "id": "m0", "metadata": {},
             "source": ["Measured:\n", "\n", f"<!-- generated: {block} -->\n",
                        f"<!-- end generated: {block} -->\n"]}
    notebook = {"cells": [code, prose], "metadata": {}, "nbformat": 4, "nbformat_minor": 5}
    page = tmp_path / "notebooks" / "toy.ipynb"
    page.parent.mkdir()
    page.write_text(json.dumps(notebook, indent=1) + "\n")
    assert documents.pages(tmp_path)[-1] == "notebooks/toy.ipynb"  # `make docs` takes it
    rendered = documents.render_notebook(page.read_text(), tmp_path, "notebooks/toy.ipynb")
    cells = json.loads(rendered)["cells"]
    assert cells[0] == code  # only Markdown is rendered
    text = "".join(cells[1]["source"])
    assert "| DGT-Map | 17/18 |" in text
    assert f"[{path.name}](../docs/runs/studies/{path.name})" in text  # from notebooks/
    assert documents.render_notebook(rendered, tmp_path, "notebooks/toy.ipynb") == rendered


def test_a_record_of_several_controllers_is_quoted_by_its_name(tmp_path):
    # `--controller paper --controller robust` names its record "…-paper+robust_…"
    path = study.publish_study(_record(variant="paper+robust"),
                               tmp_path / "docs" / "runs" / "studies")
    assert "+" in path.stem
    page = _page(tmp_path, f"study:{path.stem}/arrivals")
    text = documents.render_text(page.read_text(), {}, [], [], tmp_path, "docs/toy.md")
    assert "| DGT-Map | 17/18 |" in text

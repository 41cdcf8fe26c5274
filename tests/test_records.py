"""Run records and the docs rendered from them: every result number in the README's and
docs' generated tables comes from committed records, and the verdicts follow stated rules."""

import json
import re
import shutil
from pathlib import Path

import pytest

from dgt_lib.core import artifacts
from dgt_lib.core.config import get_profile
from dgt_lib.records import claims, documents, tables
from dgt_lib.records.publish import publish, run_name
from dgt_lib.records.record import seed_record, write_seed_record
from dgt_lib.records.study import MAX_RECORD_BYTES
from dgt_lib.stages.timings import record_stage_time
from tests.test_report import _experiment3

ROOT = Path(__file__).resolve().parent.parent
PROC = {"model": "Test CPU", "family": "1", "model_id": "2", "flags": ["avx2"], "cpus": 2}


def _record(seed: int, hill: dict[str, tuple[int, int]], *, ascents_a=(3, 3),
            processor=PROC, profile="demo") -> dict:
    """A seed's record with Experiment 1's counts and its ascent-route check."""
    return {"schema": 1, "commit": "abcdef0123", "processor": processor,
            "versions": {"python": "3", "numpy": "2", "torch": "2", "mujoco": "4"},
            "date_utc": "2026-01-02T03:04:05Z", "profile": profile, "seed": seed,
            "experiments": {"experiment1": {"counts": {"carla_cola": {
                m: list(kn) for m, kn in hill.items()}}}},
            "claims": {"hill_ascent_A": [*ascents_a, ascents_a[0] == ascents_a[1]]},
            "models": {}, "collapsed": {}, "accuracy": None, "multitask": None}


def test_more_arrivals_is_reproduced_only_when_the_intervals_are_apart():
    apart = [_record(s, {"dgt": (20, 20), "isotropic": (5, 20), "binary": (4, 20)})
             for s in range(3)]
    v = claims.more_claim("experiment1", "carla_cola", "dgt", ("isotropic", "binary"))(apart)
    assert v.reproduced is True and v.measured == "60/60 vs 15/60, 12/60"
    close = [_record(s, {"dgt": (17, 20), "single-task": (16, 20)}) for s in range(3)]
    v = claims.more_claim("experiment1", "carla_cola", "dgt", ("single-task",))(close)
    assert v.reproduced is False and "a tie with DGT-Map(ST)" in v.word
    v = claims.same_claim("experiment1", "carla_cola", "single-task", "dgt")(close)
    assert v.reproduced is True  # "as well as" holds when the intervals overlap


def test_a_route_claim_says_in_how_many_seeds_it_held():
    recs = [_record(0, {}), _record(1, {}, ascents_a=(2, 3)), _record(2, {})]
    v = claims.route_claim("hill_ascent_A")(recs)
    assert v.measured == "2 of 3 seeds (8/9 plans)" and v.reproduced is False
    assert v.word == "**not reproduced**: in 2 of 3 seeds"


def test_a_seed_record_names_its_processor_commit_and_claims(tmp_path, monkeypatch):
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    prof = get_profile("smoke")
    record = seed_record([_experiment3()], prof)
    assert record["profile"] == "smoke" and record["seed"] == prof.seed
    assert record["processor"]["cpus"] >= 1 and record["commit"]
    assert {"python", "numpy", "torch", "mujoco"} <= set(record["versions"])
    assert record["experiments"]["experiment3"]["counts"]["jeep"]["dgt"] == [1, 1]
    assert set(record["claims"]) >= {"hill_ascent_A", "ridge_jeep_sharp"}
    path = write_seed_record([_experiment3()], prof)
    assert json.loads(path.read_text())["seed"] == prof.seed


def test_publish_copies_every_seed_with_its_stage_times(tmp_path, monkeypatch):
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path / "data"))
    prof = get_profile("smoke").with_(seeds=2)
    for p in prof.seed_profiles():
        write_seed_record([_experiment3()], p)
    seed0 = prof.seed_profiles()[0]
    record_stage_time(seed0, "experiments", 30.0, run="a", started_unix_s=0, load_before=1.0)
    robust = seed0.with_overrides({"experiments.controller": "robust"})  # a variant, not the run
    record_stage_time(robust, "experiments", 99.0, run="b", started_unix_s=9, load_before=1.0)
    folder = publish(prof, dest=tmp_path / "runs")
    run = tables.Run.load(folder)
    assert run.seeds == [0, 1] and run.profile == "smoke"
    assert [t["seconds"] for t in run.records[0]["stage_times"]] == [30.0]
    assert all(len(p.read_bytes()) <= MAX_RECORD_BYTES for p in folder.glob("seed-*.json"))


def test_publish_refuses_a_record_written_by_a_run_with_changed_settings(tmp_path,
                                                                          monkeypatch):
    """A record that an older kit wrote for a variant run where the seed's own goes is
    never published as the profile's run."""
    import json

    from dgt_lib.stages.paths import results_dir

    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path / "data"))
    prof = get_profile("smoke").with_(seeds=1)
    path = write_seed_record([_experiment3()], prof.seed_profiles()[0])
    record = json.loads(path.read_text())
    assert path.parent == results_dir(prof.seed_profiles()[0])
    path.write_text(json.dumps({**record, "overrides": {"experiments.controller": "robust"}}))
    with pytest.raises(ValueError, match="changed settings"):
        publish(prof, dest=tmp_path / "runs")
    assert not (tmp_path / "runs").exists()


def test_a_run_of_two_processors_is_refused():
    other = {**PROC, "model": "Other CPU"}
    with pytest.raises(ValueError, match="several processors"):
        run_name([_record(0, {}), _record(1, {}, processor=other)])


def test_publish_names_the_missing_seed(tmp_path, monkeypatch):
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    with pytest.raises(FileNotFoundError, match="no results for seed 0"):
        publish("smoke", dest=tmp_path / "runs")


def test_the_committed_docs_are_what_the_committed_records_render():
    """`make docs` on a clean checkout changes nothing: no result in a generated block
    was typed by hand or left stale."""
    assert documents.stale(ROOT) == []


RESULT_CELL = re.compile(r"\b\d+/\d+\b|\b\d+ of \d+\b|\d ± \d|\[[+−-]?\d\.\d+, [+−-]?\d\.\d+\]")
"""What a hand-typed result looks like in a table row: arrivals k/n, a mean ± spread, an
interval."""


def test_no_table_of_the_readme_or_docs_types_a_result_outside_a_generated_block():
    """Arrivals, means ± spreads and intervals reach a table of the README or docs only
    through `make docs`, from a record: a table typed from some machine's run drifts."""
    typed = []
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        inside = False
        for n, line in enumerate(page.read_text().splitlines(), 1):
            if line.startswith("<!-- generated:"):
                inside = True
            elif line.startswith("<!-- end generated"):
                inside = False
            elif line.startswith("|") and not inside and RESULT_CELL.search(line):
                typed.append(f"{page.relative_to(ROOT)}:{n}")
    assert typed == [], "typed result tables (quote a record instead): " + ", ".join(typed)


def _copy_docs(tmp_path: Path) -> Path:
    for rel in [*documents.BLOCKS, documents.CITED, documents.FIGURE_FACTS]:
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(ROOT / rel, tmp_path / rel)
    for d in (ROOT / "docs" / "runs").iterdir():
        if d.is_dir():
            shutil.copytree(d, tmp_path / "docs" / "runs" / d.name)
    return tmp_path


def test_a_number_typed_into_a_generated_table_is_caught(tmp_path):
    root = _copy_docs(tmp_path)
    readme = root / "README.md"
    text = readme.read_text()
    start = text.index("<!-- generated: results -->")
    end = text.index("<!-- end generated: results -->")
    block = text[start:end]
    edited = block.replace("/", "/9", 1)  # one count changed by hand
    assert edited != block
    readme.write_text(text[:start] + edited + text[end:])
    assert documents.stale(root) == [readme]
    documents.write_all(root)
    assert documents.stale(root) == []


def test_every_cited_run_exists_and_a_missing_one_is_named(tmp_path):
    root = _copy_docs(tmp_path)
    (root / documents.CITED).write_text(json.dumps({"demo": "no-such-run"}))
    with pytest.raises(FileNotFoundError, match="no-such-run"):
        documents.render_all(root)


def test_every_seed_record_pooled_by_the_readme_keeps_its_processor():
    cited, _ = documents.load_runs(ROOT)
    assert cited, "the README cites no run"
    for run in cited:
        assert len({json.dumps(r["processor"], sort_keys=True) for r in run.records}) == 1
        assert all((ROOT / "docs" / "runs" / run.name / f"seed-{s}.json").stat().st_size
                   <= MAX_RECORD_BYTES for s in run.seeds)



def test_the_bottom_line_says_which_claims_reproduce_in_every_run_in_one_and_in_none():
    hill = {"dgt": (3, 3), "iso": (0, 3), "binary": (0, 3)}
    demo = tables.Run("demo_x", (_record(0, hill), _record(1, hill)))
    paper = tables.Run("paper_x", (_record(0, hill, profile="paper"),
                                   _record(1, hill, ascents_a=(2, 3), profile="paper")))
    gentle = next(c.short for c in claims.CLAIMS if c.text.startswith("Exp. 1: DGT-Map plans"))
    one = tables.bottom_line([demo])
    assert one.startswith("Of the paper's claims checked here, `demo` (2 seeds")
    assert f"reproduces 1 of 1 — {gentle}." in one
    both = tables.bottom_line([demo, paper])
    assert "`demo` (2 seeds (0, 1)" in both and "`paper` (2 seeds (0, 1)" in both
    assert f"only on `demo`: {gentle}." in both  # a route claim holds only in every seed
    assert "in both runs" not in both.split(f"only on `demo`: {gentle}.")[1]
    assert both.count(". ") <= 1, "the bottom line is at most two sentences"
    for claim in claims.CLAIMS:  # every claim checked is named once, in one group
        if not claim.ours:
            assert both.count(claim.short) <= 1


def test_one_seed_on_two_processors_stands_side_by_side_with_its_claims_and_commits():
    """The same `demo` seed recorded on two processors: both rows, each with its commit,
    and a claim that held on one and not on the other shows ✓ beside ✗."""
    other = {**PROC, "model": "Other CPU", "family": "6"}
    a = tables.Run("a", (_record(0, {"dgt": (5, 6)}, ascents_a=(3, 3)),))
    b = tables.Run("b", (_record(0, {"dgt": (6, 6)}, ascents_a=(2, 3), processor=other),))
    rows = [line for line in tables.cross_machine_table([a, b]).splitlines()
            if line.startswith("| `demo` | 0 |")]
    assert len(rows) == 4 and all("`abcdef0`, MuJoCo 4 |" in r for r in rows)
    assert "5/6" in rows[0] and "6/6" in rows[1] and "Other CPU" in rows[1]
    assert "3/3 ✓" in rows[2] and "2/3 ✗" in rows[3]
    assert "no seed" in tables.cross_machine_table([a]).lower()


def test_a_cited_run_repeated_on_another_processor_is_set_beside_it_claim_by_claim(tmp_path):
    """The cited run and a rerun of the same seeds elsewhere: one claims table with a
    column pair per processor, a verdict that flips shown in both; a rerun of other seeds
    (one seed of three) is not pooled beside it."""
    other = {**PROC, "model": "Other CPU", "family": "6"}
    hill = {"dgt": (3, 3), "iso": (0, 3), "binary": (0, 3)}
    cited = tables.Run("demo_a", (_record(0, hill), _record(1, hill)))
    again = tables.Run("demo_b", (_record(0, hill, processor=other),
                                  _record(1, hill, ascents_a=(2, 3), processor=other)))
    part = tables.Run("demo_c", (_record(0, hill, processor=other),))
    text = documents._claims_elsewhere([cited], [cited, again, part], tmp_path)
    head = next(line for line in text.splitlines() if line.startswith("| claim"))
    assert "`demo`, 2 seeds, Test CPU | verdict | `demo`, 2 seeds, Other CPU | verdict" in head
    gentle = next(line for line in text.splitlines() if "Route A" in line)
    assert "2 of 2 seeds" in gentle and "1 of 2 seeds" in gentle
    assert "runs/demo_b/" in text and "demo_c" not in text
    alone = documents._claims_elsewhere([cited], [cited, part], tmp_path)
    assert "has been repeated on another processor yet" in alone


def test_the_time_table_sets_a_profiles_other_runs_below_its_cited_one(tmp_path):
    """A learner whose machine is not the cited one sees every published run's seed time:
    the cited run first, then the profile's other runs linked, another profile's not mixed
    in; the label drops the vendor's ® marks."""
    def timed(rec: dict, seconds: float) -> dict:
        return {**rec, "stage_times": [{"stage": "collect", "seconds": seconds,
                                        "load_1min_before": 1.0}]}
    other = {**PROC, "model": "Intel(R) Xeon(R) Processor", "family": "6"}
    cited = tables.Run("demo_a", (timed(_record(0, {}), 1140.0),))
    again = tables.Run("demo_b", (timed(_record(0, {}, processor=other), 420.0),))
    paper = tables.Run("paper_c", (timed(_record(0, {}, profile="paper"), 4500.0),))
    rows = [line for line in documents._times([cited], [cited, again, paper], tmp_path)
            .splitlines() if line.startswith("| `")]
    assert len(rows) == 2
    assert "| cited | Test CPU" in rows[0] and "| 19 min |" in rows[0]
    assert "[another run](docs/runs/demo_b/) | Intel Xeon Processor (family 6" in rows[1]
    assert "| 7 min |" in rows[1]


def test_a_rerun_of_some_of_the_cited_seeds_is_set_beside_those_seeds_only(tmp_path):
    """The cited run has seeds 0–2, the rerun elsewhere 0–1: the claims table pools seeds
    0–1 of both, so a route that failed only in the cited seed 2 is reproduced in both."""
    other = {**PROC, "model": "Other CPU", "family": "6"}
    cited = tables.Run("paper_a", (_record(0, {}, profile="paper"),
                                   _record(1, {}, profile="paper"),
                                   _record(2, {}, ascents_a=(2, 3), profile="paper")))
    again = tables.Run("paper_b", (_record(0, {}, processor=other, profile="paper"),
                                   _record(1, {}, processor=other, profile="paper")))
    text = documents._claims_elsewhere([cited], [cited, again], tmp_path)
    assert "`paper`, 2 seeds (0, 1), Test CPU" in text and "runs/paper_a/" in text
    gentle = next(line for line in text.splitlines() if "Route A" in line)
    assert gentle.count("2 of 2 seeds") == 2 and "**not reproduced**" not in gentle
    whole = tables.claims_table([cited])
    assert "**not reproduced**" in next(ln for ln in whole.splitlines() if "Route A" in ln)


def test_the_hero_figure_comes_from_the_first_seed_where_the_route_claims_held(tmp_path):
    """The cited `demo` run's seed 0 sent the jeep round the ridge (0/6 straight) and seed 1
    the van round in only 3 of its 6 plans: the hero is drawn from seed 2, and the
    caption of figures drawn from another published run names that run (found by its seed's
    results, not by the processor) and says how often the claims held."""
    cited, every = documents.load_runs(ROOT)
    demo = next(r for r in cited if r.profile == "demo")
    assert tables.seeds_holding(demo.records)[0] == 2
    root = _copy_docs(tmp_path)
    other = next(r for r in every if r.profile == "demo" and r not in cited)
    held = tables.seeds_holding(other.records)
    drawn = next(r for r in other.records if r["seed"] == held[0])
    facts = {"profile": "demo", "seed": held[0], "results": tables.results_digest(drawn),
             "hero_routes": {"ascent": "A", "descent": "B", "jeep": "sharp",
                             "mercedes_van": "smooth"}}
    (root / documents.FIGURE_FACTS).write_text(json.dumps(facts))
    text = documents._hero(cited, every, root)
    assert f"seed {held[0]} of [a published `demo` run on {other.processor}](docs/runs/" in text
    assert (f"the first of its seeds in which all four route claims held ({len(held)} of its "
            f"{len(other.seeds)}; 5 of 8 in the run the tables below cite)") in text
    assert "the jeep goes straight across the sharp ridge" in text
    facts["results"] = tables.results_digest({**drawn, "claims": {}})  # results nobody published
    (root / documents.FIGURE_FACTS).write_text(json.dumps(facts))
    with pytest.raises(ValueError, match="no run in docs/runs/ recorded"):
        documents._hero(cited, every, root)

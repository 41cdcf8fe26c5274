"""``make docs``: the result tables of the README and docs rendered from published runs.

A generated block in a Markdown file sits between two comments::

    <!-- generated: claims -->
    … rendered text …
    <!-- end generated: claims -->

:data:`BLOCKS` says which function renders each block of each file, from the runs that
``docs/runs/cited.json`` names (per profile, the folder whose records the README and
docs rest on) and from every published run (the cross-machine table). ``check`` renders
without writing and lists the files whose committed text differs: a test runs it, so a
hand-edited number inside a block fails the suite, and so does a stale one. A page of
docs/ may also quote a study's table in a block named ``study:<record>/<table>``
(:mod:`dgt_lib.records.study`); every page that does is rendered too, and so is every
Markdown cell of a notebook that does (the notebook's JSON is otherwise left as it is).
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from statistics import median

from dgt_lib.records import study, tables
from dgt_lib.records.provenance import ROOT
from dgt_lib.records.tables import Run

CITED = "docs/runs/cited.json"
"""Which published run each profile's tables rest on: ``{"demo": "<run folder>", …}``."""


def load_runs(root: Path = ROOT) -> tuple[list[Run], list[Run]]:
    """(the cited runs in ``cited.json``'s order, every published run)."""
    runs_dir = root / "docs" / "runs"
    every = [Run.load(d) for d in sorted(runs_dir.iterdir())
             if d.is_dir() and any(d.glob("seed-*.json"))] if runs_dir.exists() else []
    cited_names = json.loads((root / CITED).read_text()) if (root / CITED).exists() else {}
    by_name = {r.name: r for r in every}
    missing = [n for n in cited_names.values() if n not in by_name]
    if missing:
        raise FileNotFoundError(f"{CITED} names runs with no records: {', '.join(missing)}")
    return [by_name[n] for n in cited_names.values()], every


def _captions(runs: Sequence[Run], prefix: str) -> str:
    return "\n".join(f"- {tables.caption(r, prefix)}" for r in runs) + "\n"


def _results(cited: Sequence[Run], _every, _root: Path) -> str:
    return ("Pooled over the seeds of:\n\n" + _captions(cited, "docs/") + "\n"
            + tables.results_table(cited))


def _claims(cited: Sequence[Run], _every, _root: Path) -> str:
    return "Checked over:\n\n" + _captions(cited, "docs/") + "\n" + tables.claims_table(cited)


FIGURE_FACTS = "docs/figures/figures.json"
"""What ``make figures`` drew, from which run (:data:`dgt_lib.app.figures.FACTS`)."""

ROUTE_WORDS = {"A": "by Route A", "B": "by Route B", "other": "by neither route",
               "sharp": "straight across the sharp ridge",
               "smooth": "round by the smoothed section", "no path": "finds no path"}


def _hero(cited: Sequence[Run], every: Sequence[Run], root: Path) -> str:
    facts = json.loads((root / FIGURE_FACTS).read_text())
    run = next((r for r in [*cited, *every] if r.profile == facts["profile"] and any(
        x["seed"] == facts["seed"] and tables.results_digest(x) == facts.get("results")
        for x in r.records)), None)
    if run is None:
        raise ValueError(f"{FIGURE_FACTS}: the figures' `{facts['profile']}` run has results "
                         "no run in docs/runs/ recorded: draw them from a published run's data")
    routes = {k: ROUTE_WORDS.get(v, v) for k, v in facts["hero_routes"].items()}
    jeep, van = (tables.verdicts_by_key(run)[k] for k in ("ridge_jeep_sharp", "ridge_smooth"))
    held = tables.seeds_holding(run.records)
    which = ("the run the tables below cite" if run in cited else
             f"[a published `{run.profile}` run on {run.processor}](docs/runs/{run.name}/)")
    cite = "".join(f"; {len(tables.seeds_holding(r.records))} of {len(r.seeds)} in the run the "
                   "tables below cite" for r in cited if r.profile == run.profile and r != run)
    chosen = (f", the first of its seeds in which all four route claims held ({len(held)} of "
              f"its {len(run.seeds)}{cite})" if held[:1] == [facts["seed"]] else "")
    return (f"*Drawn by `make figures` from seed {facts['seed']} of {which}"
            f"{chosen}. Left: carla_cola's DGT-Map cost layer for heading north on "
            f"the hill (bright = costly) and DGT-Map's plans for Experiment 1's first ascent, "
            f"{routes['ascent']}, and first descent, {routes['descent']}. Middle and right: "
            f"the same ridge through two heads of the same network, the jeep's and the "
            f"mercedes_van's, and each vehicle's plan for Experiment 2's first northbound "
            f"query: the jeep goes {routes['jeep']}, the van {routes['mercedes_van']}. Over "
            f"the run's {tables.n_seeds(len(run.seeds))} the jeep's plans went straight across in "
            f"{jeep.measured}, the van's round in {van.measured}.*\n")


def _times(cited: Sequence[Run], every: Sequence[Run], _root: Path) -> str:
    """One seed's stage time per published run: each profile's cited run, then the
    profile's other published runs (a learner's machine is rarely the cited one's)."""
    lines = ["| profile | run | processor | one seed's stages, median over its seeds | load |",
             "| --- | --- | --- | --- | --- |"]
    for run in cited:
        for r in [run, *(o for o in every if o.profile == run.profile and o.name != run.name)]:
            times = [t for rec in r.records for t in rec.get("stage_times", [])]
            loads = [t["load_1min_before"] for t in times if t.get("load_1min_before") is not None]
            if times:
                which = "cited" if r is run else f"[another run](docs/runs/{r.name}/)"
                minutes = median(sum(t["seconds"] for t in rec.get("stage_times", []))
                                 for rec in r.records) / 60
                lines.append(f"| `{r.profile}` ({tables.n_seeds(len(r.seeds))}) | {which} | "
                             f"{r.processor} | {minutes:.0f} min | {min(loads, default=0):.1f}–"
                             f"{max(loads, default=0):.1f} at the stages' starts |")
    return "\n".join(lines) + "\n"


def _per_run(cited: Sequence[Run], _every, _root: Path) -> str:
    return "\n".join(f"## `{r.profile}`\n\n" + tables.seeds_sections(r) for r in cited)


def _claims_elsewhere(cited: Sequence[Run], every: Sequence[Run], _root: Path) -> str:
    """Each cited run beside its reruns on other processors, claim by claim, over the seeds
    a rerun ran (two or more of the cited run's: one seed is the per-seed table's)."""
    groups: list[list[Run]] = []
    for run in cited:
        elsewhere = [r for r in every if r.profile == run.profile and r.processor != run.processor
                     and len(r.seeds) > 1 and set(r.seeds) <= set(run.seeds)]
        for seeds in dict.fromkeys(tuple(r.seeds) for r in elsewhere):  # the cited, cut to them
            groups.append([Run(run.name, tuple(x for x in run.records if x["seed"] in seeds)),
                           *(r for r in elsewhere if tuple(r.seeds) == seeds)])
    blocks = [_captions(g, "") + "\n" + tables.claims_table(g, by_processor=True) for g in groups]
    return "\n".join(blocks) or "No cited run has been repeated on another processor yet.\n"


Renderer = Callable[[Sequence[Run], Sequence[Run], Path], str]
"""(cited runs, every run, the checkout's root) → the block's Markdown."""
BLOCKS: dict[str, dict[str, Renderer]] = {
    "README.md": {"bottom-line": lambda cited, _every, _root: tables.bottom_line(cited),
                  "hero": _hero, "results": _results, "claims": _claims, "times": _times},
    "docs/results.md": {"per-run": _per_run, "cross-machine":
                        lambda _cited, every, _root: tables.cross_machine_table(every),
                        "claims-elsewhere": _claims_elsewhere},
    "docs/runs/README.md": {"index": lambda _cited, every, _root: (
        _captions(every, "../") if every else "No run published yet.\n")},
}
"""Each file's generated blocks and the function that renders each."""

_BLOCK = re.compile(r"(<!-- generated: (?P<name>[\w:./+-]+) -->\n)(?P<body>.*?)"
                    r"(<!-- end generated: (?P=name) -->)", re.S)


def render_text(text: str, renderers: dict[str, Renderer], cited, every, root: Path,
                path: str) -> str:
    """``text`` with each generated block replaced by its renderer's output (a study's
    block, ``study:…``, by :func:`~dgt_lib.records.study.render_block`); ValueError for a
    block without a renderer or a renderer whose block is missing."""
    found = [m["name"] for m in _BLOCK.finditer(text)
             if not m["name"].startswith(study.BLOCK_PREFIX)]
    unknown, missing = set(found) - set(renderers), set(renderers) - set(found)
    if unknown or missing:
        raise ValueError(f"{path}: generated blocks without a renderer {sorted(unknown)}, "
                         f"renderers without a block {sorted(missing)}")

    def body(m: re.Match) -> str:
        if m["name"].startswith(study.BLOCK_PREFIX):
            return study.render_block(m["name"], root / path, root)
        return renderers[m["name"]](cited, every, root)

    return _BLOCK.sub(lambda m: m.group(1) + body(m) + m.group(4), text)


def pages(root: Path = ROOT) -> list[str]:
    """The files ``make docs`` renders: those of :data:`BLOCKS`, every page of docs/ and
    every notebook that quotes a study (``<!-- generated: study:…``)."""
    marker = f"<!-- generated: {study.BLOCK_PREFIX}"
    quoting = sorted(p.relative_to(root).as_posix()
                     for p in [*(root / "docs").rglob("*.md"),
                               *(root / "notebooks").glob("*.ipynb")]
                     if marker in p.read_text())
    return list(BLOCKS) + [p for p in quoting if p not in BLOCKS]


def render_notebook(text: str, root: Path, path: str) -> str:
    """A notebook's JSON ``text`` with the study blocks of its Markdown cells rendered
    (:func:`render_text`), written back as Jupyter writes it (one-space indent)."""
    notebook = json.loads(text)
    for cell in notebook["cells"]:
        if cell["cell_type"] != "markdown":
            continue
        source = cell["source"]
        old = "".join(source) if isinstance(source, list) else source
        new = render_text(old, {}, (), (), root, path)
        if new != old:
            cell["source"] = new.splitlines(keepends=True) if isinstance(source, list) else new
    return json.dumps(notebook, indent=1, ensure_ascii=False) + "\n"


def render_all(root: Path = ROOT) -> dict[Path, str]:
    """{file: its text with every generated block rendered} for :func:`pages`."""
    cited, every = load_runs(root)
    out = {}
    for rel in pages(root):
        text = (root / rel).read_text()
        out[root / rel] = (render_notebook(text, root, rel) if rel.endswith(".ipynb") else
                           render_text(text, BLOCKS.get(rel, {}), cited, every, root, rel))
    return out


def stale(root: Path = ROOT) -> list[Path]:
    """The files whose committed text differs from what their records render."""
    return [p for p, text in render_all(root).items() if p.read_text() != text]


def write_all(root: Path = ROOT) -> list[Path]:
    """Render every generated block in place; returns the files that changed."""
    changed = []
    for path, text in render_all(root).items():
        if path.read_text() != text:
            path.write_text(text)
            changed.append(path)
    return changed

"""Notebooks are committed clean: no outputs, the python3 kernel, an opening that teaches,
no development history, links that resolve (numbers pointed to by a link to the page that
has them), a time warning above every cell that can run past 30 s on `demo`, and an end
that says what was learned (## Takeaways) with the run's numbers."""

import json
import re
from pathlib import Path

import pytest

NOTEBOOKS = sorted((Path(__file__).resolve().parent.parent / "notebooks").glob("*.ipynb"))


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_is_clean_and_opens_with_what_it_teaches(path):
    nb = json.loads(path.read_text())
    assert nb["metadata"]["kernelspec"]["name"] == "python3"
    cells = nb["cells"]
    assert cells[0]["cell_type"] == "markdown", "open with what the notebook teaches"
    assert "paper" in "".join(cells[0]["source"]).lower(), "say which part of the paper it follows"
    for cell in cells:
        if cell["cell_type"] == "code":
            assert cell.get("outputs", []) == [], f"{path.name}: strip outputs"
            assert cell.get("execution_count") is None, f"{path.name}: strip execution counts"
    code = "".join("".join(c["source"]) for c in cells if c["cell_type"] == "code")
    assert "get_profile" in code, "size the notebook through DGT_PROFILE / get_profile()"


HISTORY = re.compile(r"\bissue \d+|\bsessions?\b|\b(?:an? )?(?:earlier|previous|older) version\b|"
                     r"\bno longer\b|\bleft for later\b|`[0-9a-f]{7,40}`", re.IGNORECASE)
GENERATED = re.compile(r"<!-- generated: (?P<name>\S+) -->.*?<!-- end generated: (?P=name) -->",
                       re.S)
"""A table rendered from a record by `make docs`: its caption names the run's commit."""


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_speaks_of_the_kit_not_of_how_it_was_built(path):
    text = "".join("".join(c["source"]) for c in json.loads(path.read_text())["cells"])
    text = GENERATED.sub("", text)  # a generated table names its run's commit: provenance
    assert not HISTORY.findall(text), "development history (issues, sessions, old versions, hashes)"


HEAVY = re.compile(r"\b(?:collect_episodes|ensure_bev|ensure_dataset|load_model"
                   r"|ensure_world_costmaps|ensure_experiment|ensure_ground_truths"
                   r"|ensure_costmap_accuracy|explore)\(")
TIMED = ("01_terrain_and_bev", "02_locomotion_labels", "07_experiment2_ridge",
         "08_experiment3_multitask", "09_costmap_accuracy", "10_incremental_mapping")
"""Notebooks whose cold-cache cells are checked for a time warning."""


@pytest.mark.parametrize("stem", TIMED)
def test_the_first_cell_that_builds_on_a_cold_cache_warns_of_the_time(stem):
    cells = json.loads((NOTEBOOKS[0].parent / f"{stem}.ipynb").read_text())["cells"]
    first = next(i for i, c in enumerate(cells)
                 if c["cell_type"] == "code" and HEAVY.search("".join(c["source"])))
    above = "".join(cells[first - 1]["source"])
    assert cells[first - 1]["cell_type"] == "markdown" and "*Time.*" in above
    assert "smoke" in above and "DGT_PROFILE=smoke" in above and " s " in above


# ----------------------------------------------------------------------------- links
ROOT = NOTEBOOKS[0].parent.parent
LINK = re.compile(r"(?<!!)\[([^\]]*)\]\(([^)\s]+)\)")
CODE_SPAN = re.compile(r"```.*?```|`[^`\n]*`", re.DOTALL)


def _markdown(path):
    return [(i, "".join(c["source"])) for i, c in enumerate(json.loads(path.read_text())["cells"])
            if c["cell_type"] == "markdown"]


def github_slugs(markdown_text):
    """The anchors GitHub gives a Markdown file's headings: lower case, punctuation dropped,
    spaces to hyphens, a repeated slug numbered -1, -2, …"""
    slugs, seen = set(), {}
    in_fence = False
    for line in markdown_text.splitlines():
        if line.startswith("```"):
            in_fence = not in_fence
        m = None if in_fence else re.match(r"#{1,6}\s+(.*?)\s*#*\s*$", line)
        if not m:
            continue
        text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", m.group(1))
        slug = re.sub(r"[^\w\- ]", "", text.lower()).replace(" ", "-")
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        slugs.add(slug if n == 0 else f"{slug}-{n}")
    return slugs


def test_github_slugs_follow_githubs_rule():
    text = "# Speed\n## The `paper` run\n## Why MPPI crawls\n## Why MPPI crawls\n" \
           "## `demo` profile, 3 seeds\n```\n# not a heading\n```\n"
    assert github_slugs(text) == {"speed", "the-paper-run", "why-mppi-crawls",
                                  "why-mppi-crawls-1", "demo-profile-3-seeds"}


def _broken_links(path, texts):
    """The links of ``texts`` (Markdown, (where, text) pairs) written in ``path`` that name
    no file, or no heading of a Markdown file."""
    broken = []
    for where, text in texts:
        for _, target in LINK.findall(CODE_SPAN.sub("", text)):
            if re.match(r"[a-z]+:", target):  # https:, mailto:
                continue
            file, _, anchor = target.partition("#")
            resolved = (path.parent / file).resolve() if file else path
            if not resolved.exists():
                broken.append(f"{where}: {target} (no such file)")
            elif anchor and resolved.suffix == ".md" and \
                    anchor not in github_slugs(resolved.read_text()):
                broken.append(f"{where}: {target} (no such heading)")
    return broken


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_every_link_to_a_file_of_the_repository_resolves(path):
    broken = _broken_links(path, [(f"cell {i}", text) for i, text in _markdown(path)])
    assert not broken, "broken links: " + "; ".join(broken)


def test_the_notebooks_readme_links_resolve():
    readme = NOTEBOOKS[0].parent / "README.md"
    broken = _broken_links(readme, [("README.md", readme.read_text())])
    assert not broken, "broken links: " + "; ".join(broken)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_numbers_are_pointed_to_by_a_link_to_the_page_that_has_them(path):
    """No "(README)" or "see the README": a pointer names the page that holds the number,
    as a link (README.md's own sections are linked like any other page)."""
    bare = [f"cell {i}: …{m.string[max(0, m.start() - 60):m.end() + 20]}…"
            for i, text in _markdown(path)
            for m in re.finditer(r"\bREADME\b", CODE_SPAN.sub("", LINK.sub("", text)))]
    assert not bare, "point to the page by a link, not to 'the README': " + "; ".join(bare)


# ----------------------------------------------------------------------------- takeaways
NUMBERED = [p for p in NOTEBOOKS if re.match(r"\d\d[a-z]?_", p.name)]
@pytest.mark.parametrize("path", NUMBERED, ids=lambda p: p.name)
def test_every_notebook_ends_with_its_takeaways_and_the_numbers_they_rest_on(path):
    """The last Markdown cell, headed "## Takeaways", says what was learned; after it comes at
    most one code cell, which prints the numbers of this run the takeaways rest on."""
    cells = json.loads(path.read_text())["cells"]
    last = max(i for i, c in enumerate(cells) if c["cell_type"] == "markdown")
    text = "".join(cells[last]["source"])
    assert "Takeaways" in text and text.startswith("## Takeaways"), "end with ## Takeaways"
    assert 3 <= len(re.findall(r"^- ", text, re.M)) <= 5, "three to five bullets"
    after = cells[last + 1:]
    assert len(after) <= 1 and all(c["cell_type"] == "code" for c in after)
    if after:
        assert "print(" in "".join(after[0]["source"]), "print the run's numbers"


# ----------------------------------------------------------------------------- time warnings
SLOW = {
    "03_multitask_training": ("f0fe47ec", "420cc795"),  # trains five models; four widths
    "04_directional_inference": ("06d5dcb1",),  # the literal procedure
    "04b_beyond_fast_inference": ("b-reference", "b-561fadcc"),  # literal; trains PooledNet
    "05_hybrid_astar": ("13b54ba7",),  # compiles the planner's kernels on a fresh install
    "06_experiment1_hill": ("61184f17",),  # every trial of Experiment 1
    "07_experiment2_ridge": ("3803fe13",),
    "08_experiment3_multitask": ("00ae3a50",),
    "09_costmap_accuracy": ("c10", "c12", "c17"),  # ground truth, costmaps, scores
    "10_incremental_mapping": ("incr-03",),  # a jeep explores with a camera
    "12_your_robot": ("log-7b", "log-7d", "log-7f"),  # records; conditioned net; costmap
}
"""Cells that can run past 30 s on a `demo` cache (cold or warm) besides each notebook's
first cell that builds on a cold cache."""
WARNING = re.compile(r"\*Time[.:]\*|⏱")
DURATION = re.compile(r"\d+ (?:s|min)\b")


def _needs_warning(cells, stem):
    first = [i for i, c in enumerate(cells)
             if c["cell_type"] == "code" and HEAVY.search("".join(c["source"]))][:1]
    ids = [c.get("id") for c in cells]
    return sorted({*first, *(ids.index(cid) for cid in SLOW.get(stem, ()))})


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_every_cell_that_can_take_more_than_30_s_on_demo_warns_of_the_time(path):
    cells = json.loads(path.read_text())["cells"]
    unwarned = []
    for i in _needs_warning(cells, path.stem):
        above = "".join(cells[i - 1]["source"]) if cells[i - 1]["cell_type"] == "markdown" else ""
        if not (WARNING.search(above) and "demo" in above and DURATION.search(above)):
            unwarned.append(f"cell {i} ({cells[i].get('id')})")
    assert not unwarned, ("say in the Markdown just above how long it takes on `demo` "
                          "(*Time.* or ⏱, seconds or minutes): " + ", ".join(unwarned))

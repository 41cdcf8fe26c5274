"""Notebooks are committed clean: no outputs, the python3 kernel, an opening that teaches,
no development history, and a time warning before the first cell that builds on a cold
cache."""

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


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_speaks_of_the_kit_not_of_how_it_was_built(path):
    text = "".join("".join(c["source"]) for c in json.loads(path.read_text())["cells"])
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

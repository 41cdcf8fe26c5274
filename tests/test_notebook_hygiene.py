"""Notebooks are committed clean: no outputs, the python3 kernel, an opening that teaches."""

import json
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

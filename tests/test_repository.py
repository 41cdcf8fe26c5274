"""A clone is self-contained: nothing points outside the repository, and the documents the
README links to are in it."""

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
OUTSIDE = ("../shared", "DESIGN.md", "dgt-map.tex")
"""Files of the workspace the kit was built in, which a clone does not have."""


def _tracked_files() -> list[Path]:
    """The files git tracks (or, outside a git checkout, every file but caches and data)."""
    try:
        names = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True,
                               check=True).stdout.splitlines()
    except (OSError, subprocess.CalledProcessError):
        skip = {".git", ".venv", "data", "__pycache__", ".pytest_cache", ".ruff_cache"}
        return [p for p in ROOT.rglob("*")
                if p.is_file() and not skip & set(p.relative_to(ROOT).parts)]
    return [ROOT / n for n in names if (ROOT / n).is_file()]


def test_no_file_points_outside_the_repository():
    offenders = []
    for path in _tracked_files():
        if path.relative_to(ROOT).parts[0] == "tests":
            continue
        try:
            text = path.read_text()
        except UnicodeDecodeError:
            continue
        offenders += [f"{path.relative_to(ROOT)}: {word}" for word in OUTSIDE if word in text]
    assert offenders == []


@pytest.mark.parametrize("document", ["README.md", "docs/ARCHITECTURE.md", "docs/speed.md"])
def test_every_relative_link_of_the_documentation_exists(document):
    text = (ROOT / document).read_text()
    links = re.findall(r"\]\(([^)#\s]+)[^)]*\)", text)
    relative = [link for link in links if "://" not in link]
    assert relative, f"{document} links to nothing in the repository"
    missing = [link for link in relative if not (ROOT / document).parent.joinpath(link).exists()]
    assert missing == []


def test_architecture_document_names_every_sub_package():
    text = (ROOT / "docs" / "ARCHITECTURE.md").read_text()
    packages = [p.name for p in (ROOT / "dgt_lib").iterdir() if (p / "__init__.py").exists()]
    assert [p for p in packages if f"`{p}" not in text] == []

"""A clone is self-contained: nothing points outside the repository, and the documents the
README links to are in it."""

import re
import subprocess
import sys
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


DOCUMENTS = sorted(["README.md",
                    *(str(p.relative_to(ROOT)) for p in (ROOT / "docs").rglob("*.md"))])
"""The documentation a reader follows links through: the README and every page of docs/."""


def _prose(text: str) -> str:
    """Markdown without its fenced code blocks (a link-like string in code is not a link)."""
    return re.sub(r"^```.*?^```", "", text, flags=re.MULTILINE | re.DOTALL)


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading.strip().lower())  # a link: its text
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    """Every anchor a link may name in ``path``: its headings' slugs (a repeated heading
    gets -1, -2, … as on GitHub)."""
    seen: dict[str, int] = {}
    out = set()
    for line in _prose(path.read_text()).splitlines():
        if match := re.match(r"#{1,6}\s+(.*)", line):
            slug = _slug(match.group(1))
            out.add(slug if slug not in seen else f"{slug}-{seen[slug]}")
            seen[slug] = seen.get(slug, 0) + 1
    return out


def _broken_links(document: str) -> list[str]:
    """The relative links and images of ``document`` whose file, or heading, is missing."""
    path = ROOT / document
    broken = []
    for target in re.findall(r"\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)", _prose(path.read_text())):
        if "://" in target or target.startswith("mailto:"):
            continue
        file, _, anchor = target.partition("#")
        linked = path.parent.joinpath(file) if file else path
        if not linked.exists():
            broken.append(f"{target}: no such file")
        elif anchor and linked.suffix == ".md" and anchor not in _anchors(linked):
            broken.append(f"{target}: no such heading")
    return broken


def test_the_documentation_has_pages_to_check():
    assert {"README.md", "docs/ARCHITECTURE.md", "docs/results.md"} <= set(DOCUMENTS)


@pytest.mark.parametrize("document", DOCUMENTS)
def test_every_relative_link_and_image_of_the_documentation_resolves(document):
    assert _broken_links(document) == []


def test_a_broken_link_a_missing_image_and_a_missing_heading_are_found(tmp_path, monkeypatch):
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "a.md").write_text("# A page\n\n## The `paper` run\n")
    (tmp_path / "README.md").write_text(
        "[ok](docs/a.md) [ok](docs/a.md#the-paper-run) [ok](#top) ![gone](docs/x.png)\n"
        "[gone](docs/b.md) [gone](docs/a.md#the-demo-run) [web](https://example.org)\n"
        "```\n[in code](nowhere.md)\n```\n# Top\n")
    assert _broken_links("README.md") == ["docs/x.png: no such file", "docs/b.md: no such file",
                                          "docs/a.md#the-demo-run: no such heading"]


HISTORY = (r"\bissue \d+", r"\bsession\b", r"left for later", r"not done this time",
           r"this session")
"""Development-log wording the product never uses (the kit speaks of itself, not of how it
was built)."""


@pytest.mark.parametrize("document", DOCUMENTS)
def test_the_documentation_tells_no_development_history(document):
    text = (ROOT / document).read_text()
    assert [w for w in HISTORY if re.search(w, text, flags=re.IGNORECASE)] == []


def test_the_readme_is_short_and_names_no_commit_by_hand():
    """Commits appear only where `make docs` renders them from run records."""
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 250
    typed = re.sub(r"<!-- generated: ([\w-]+) -->.*?<!-- end generated: \1 -->", "", text,
                   flags=re.S)
    hashes = re.findall(r"`([0-9a-f]{7,40})`", typed)
    assert hashes == []


def _linked_pages(document: Path) -> set[Path]:
    """The files a document links to (a folder stands for its README.md)."""
    out = set()
    for target in re.findall(r"\]\(([^)#\s]+)", document.read_text()):
        if "://" in target:
            continue
        path = (document.parent / target).resolve()
        out.add(path / "README.md" if path.is_dir() else path)
    return out


def test_every_page_of_the_docs_is_linked_from_the_readme_or_another_page():
    pages = sorted((ROOT / "docs").rglob("*.md"))
    linked = set().union(*(_linked_pages(d) for d in [ROOT / "README.md", *pages]))
    assert [p.relative_to(ROOT).as_posix() for p in pages if p.resolve() not in linked] == []


def test_architecture_document_names_every_sub_package():
    text = (ROOT / "docs" / "ARCHITECTURE.md").read_text()
    packages = [p.name for p in (ROOT / "dgt_lib").iterdir() if (p / "__init__.py").exists()]
    assert [p for p in packages if f"`{p}" not in text] == []

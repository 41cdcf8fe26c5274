"""The set-up files cannot drift apart: pyproject ↔ environment.yml, README ↔ CI."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

tomllib = pytest.importorskip("tomllib")  # Python ≥ 3.11

ROOT = Path(__file__).resolve().parent.parent


def _name(requirement: str) -> str:
    return re.split(r"[<>=!~\[ ;]", requirement.strip(), maxsplit=1)[0].lower()


def test_environment_yml_lists_the_same_dependencies_as_pyproject():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    declared = set(project["dependencies"]) | set(project["optional-dependencies"]["dev"])
    env_lines = (ROOT / "environment.yml").read_text().splitlines()
    pip_reqs = {
        line.strip()[2:].strip()
        for line in env_lines
        if line.strip().startswith("- ") and line.startswith("      ")
    }
    pip_reqs.discard("-e .[dev]")
    assert {_name(r) for r in pip_reqs} == {_name(r) for r in declared}
    assert pip_reqs == declared, "version bounds differ between environment.yml and pyproject"
    assert any("-e .[dev]" in line for line in env_lines)


def test_ci_runs_the_readme_test_command():
    readme = (ROOT / "README.md").read_text()
    commands = re.findall(r"^\s*(make \w+)\s*(?:#.*)?$", readme, flags=re.MULTILINE)
    assert "make test" in commands and "make reproduce" in commands
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    run_lines = [line.strip() for line in ci if line.strip() and not line.startswith("#")]
    assert run_lines[-1] == "make test"


def test_torch_is_never_pulled_unpinned_on_cpu_machines():
    makefile = (ROOT / "Makefile").read_text()
    assert "torch==2.13.0" in makefile  # the CPU wheel, installed before the package
    assert makefile.index("torch==2.13.0") < makefile.index("pip install -q -e '.[dev]'")


def test_code_passes_ruff():
    ruff = Path(sys.executable).parent / "ruff"
    if not ruff.exists():
        pytest.skip("ruff is not installed in this environment")
    done = subprocess.run([str(ruff), "check", "dgt_lib", "tests", "benchmarks", "studies"],
                          cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr


IMPORT_NAMES = {"opencv-python-headless": "cv2", "rerun-sdk": "rerun",
                "scikit-image": "skimage"}
"""Distributions whose import name is not their own name."""

APPLICATIONS = {"jupyterlab": "the notebook app of the README's `jupyter lab notebooks/`"}
"""Runtime dependencies that are run, not imported."""


def _imported_top_level_modules() -> set[str]:
    """Top-level modules imported by the library, the notebooks, the tests, the benchmarks
    and the studies."""
    import ast
    import json

    modules: set[str] = set()
    sources = [p.read_text() for d in ("dgt_lib", "tests", "benchmarks", "studies")
               for p in (ROOT / d).rglob("*.py")]
    for nb in (ROOT / "notebooks").glob("*.ipynb"):
        cells = json.loads(nb.read_text())["cells"]
        code = ["".join(c["source"]) for c in cells if c["cell_type"] == "code"]
        sources += ["\n".join(line for line in cell.splitlines()
                              if not line.lstrip().startswith(("%", "!"))) for cell in code]
    for source in sources:
        for node in ast.walk(ast.parse(source)):
            if isinstance(node, ast.Import):
                modules |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                modules.add(node.module.split(".")[0])
    return modules


def test_every_runtime_dependency_is_used():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    imported = _imported_top_level_modules()
    unused = [req for req in project["dependencies"] if _name(req) not in APPLICATIONS
              and IMPORT_NAMES.get(_name(req), _name(req).replace("-", "_")) not in imported]
    assert unused == [], "declared in pyproject.toml but imported nowhere"


def test_rerun_is_pinned_to_the_minor_version_whose_api_the_code_uses():
    """rerun changes its logging API between minor versions (0.x): an upper bound keeps a
    fresh install on the version the recordings were written for."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    rerun = next(r for r in project["dependencies"] if _name(r) == "rerun-sdk")
    assert re.search(r"<\s*0\.\d+", rerun), rerun


def test_the_license_file_is_the_license_pyproject_declares():
    license_ = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["license"]
    text = (ROOT / "LICENSE").read_text()
    assert license_ == {"text": "MIT"}
    assert text.startswith("MIT License") and "the dgt-kit authors" in text
    assert "Permission is hereby granted, free of charge" in text


def test_citation_file_cites_the_kit_and_the_paper():
    yaml = pytest.importorskip("yaml")
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert cff["cff-version"] == "1.2.0"
    assert cff["type"] == "software" and cff["message"] and cff["authors"]
    assert str(cff["version"]) == project["version"]
    assert cff["license"] == project["license"]["text"]
    paper = cff["preferred-citation"]
    assert paper["title"].startswith("DGT-Map: Directional Global Traversability Mapping")
    assert [a["family-names"] for a in paper["authors"]] == ["Singh", "Noori", "Xiao",
                                                             "Chamzas"]


def test_the_named_vehicles_files_are_package_data():
    """An installed package (a wheel) carries the files the named vehicles are read from."""
    from fnmatch import fnmatch

    from dgt_lib.core.vehicles import NAMED_VEHICLE_DIR

    data = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    globs = data["package-data"]["dgt_lib.core"]
    core = ROOT / "dgt_lib" / "core"
    files = [p.relative_to(core).as_posix() for p in NAMED_VEHICLE_DIR.glob("*")]
    assert len(files) == 4 and all(any(fnmatch(f, g) for g in globs) for f in files)

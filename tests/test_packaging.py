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
    done = subprocess.run([str(ruff), "check", "dgt_lib", "tests", "benchmarks"], cwd=ROOT,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr

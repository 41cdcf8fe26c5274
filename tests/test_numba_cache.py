"""The planner's compiled code follows an edit to any of its compiled modules: numba's own
cache checks a cached function against its own file only."""

import hashlib
import subprocess
import sys
from pathlib import Path

import dgt_lib.navigation.planner as planner

HELPER = "from numba import njit\n\n@njit(cache=True)\ndef helper():\n    return {}\n"
CALLER = ("from numba import njit\nfrom pkg.compiled_helper import helper\n\n"
          "@njit(cache=True)\ndef search():\n    return helper()\n")
RUN = """import sys
from pathlib import Path
sys.path.insert(0, sys.argv[1])
if sys.argv[2] == "guarded":
    from dgt_lib.navigation.planner import drop_stale_numba_cache
    drop_stale_numba_cache(Path(sys.argv[1]) / "pkg")
from pkg.compiled import search
print(search())
"""


def _search(root: Path, mode: str) -> str:
    out = subprocess.run([sys.executable, "-c", RUN, str(root), mode], capture_output=True,
                         text=True, check=True)
    return out.stdout.strip()


def test_an_edited_helper_is_compiled_again_instead_of_served_from_the_cache(tmp_path):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "compiled_helper.py").write_text(HELPER.format(1))
    (pkg / "compiled.py").write_text(CALLER)
    assert _search(tmp_path, "guarded") == "1"
    assert list((pkg / "__pycache__").glob("compiled.search-*.nbc"))  # cached on disk

    (pkg / "compiled_helper.py").write_text(HELPER.format(2))
    assert _search(tmp_path, "bare") == "1"  # numba alone runs the stale helper
    assert _search(tmp_path, "guarded") == "2"
    assert _search(tmp_path, "guarded") == "2"  # and caches the new code again
    assert list((pkg / "__pycache__").glob("compiled.search-*.nbc"))


def test_the_planner_package_stamps_its_cache_with_its_compiled_sources():
    package = Path(planner.__file__).parent
    sources = b"".join(p.read_bytes() for p in sorted(package.glob("compiled*.py")))
    stamp = package / "__pycache__" / "compiled.sources.sha256"
    assert stamp.read_text() == hashlib.sha256(sources).hexdigest()

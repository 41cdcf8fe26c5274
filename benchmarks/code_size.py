"""How big is the paper path? Code lines of the ``dgt_lib`` modules that notebooks 01–09 reach.

    .venv/bin/python benchmarks/code_size.py                  # this checkout's dgt_lib
    .venv/bin/python benchmarks/code_size.py /other/dgt_lib   # another checkout's

The paper path is every ``dgt_lib`` module a notebook 01–09 imports (``import dgt_lib as
dgt`` then ``dgt.get_world`` counts as the module that name is loaded from), closed over
the modules those import — at module level, in functions or under ``TYPE_CHECKING`` — with
the packages that hold them; ``beyond/`` (what goes beyond the paper) is left out. A code
line is a line with code on it: docstrings, comments and blank lines are not counted.
Prints the lines per sub-package and the total, then the whole package's for comparison.
"""

from __future__ import annotations

import argparse
import ast
import io
import json
import tokenize
from pathlib import Path

PAPER_NOTEBOOKS = tuple(f"{i:02d}_" for i in range(1, 10))
"""The notebooks of the paper (their file names start with these); 10 goes beyond it."""
SKIPPED = "beyond"
"""The sub-package left out of the paper path."""


def code_lines(source: str) -> int:
    """The lines of ``source`` with code on them: not blank, not only a comment, not part
    of a docstring (a string standing alone as a statement)."""
    tree = ast.parse(source)
    docs = set()
    for node in ast.walk(tree):
        if (isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)
                and isinstance(node.value.value, str)):
            docs.update(range(node.lineno, node.end_lineno + 1))
    lines = set()
    skip = {tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT,
            tokenize.ENCODING, tokenize.ENDMARKER}
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type not in skip:
            lines.update(range(tok.start[0], tok.end[0] + 1))
    return len(lines - docs)


def package_modules(package: Path) -> dict[str, Path]:
    """``{"dgt_lib.core.config": path, …}`` of every module under ``package``."""
    mods = {}
    for path in sorted(package.rglob("*.py")):
        parts = path.relative_to(package.parent).with_suffix("").parts
        mods[".".join(p for p in parts if p != "__init__")] = path
    return mods


def lazy_api(package: Path) -> dict[str, str]:
    """The package's public names and the module each is loaded from (``_API`` of its
    ``__init__.py``: ``dgt.get_world`` is ``dgt_lib.world.terrain.get_world``)."""
    for node in ast.parse((package / "__init__.py").read_text()).body:
        if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "_API":
            return ast.literal_eval(node.value)
    return {}


def imported_modules(tree: ast.AST, modules: dict[str, Path], api: dict[str, str],
                     root: str) -> set[str]:
    """The package's modules a syntax tree imports (any import statement, anywhere), with
    the public names used through an ``import <root> as x`` alias."""
    out, aliases = set(), set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for alias in node.names:
                sub = f"{node.module}.{alias.name}"
                if sub in modules:
                    out.add(sub)
                elif node.module == root and alias.name in api:
                    out.add(api[alias.name])
                else:
                    out.add(node.module)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                out.add(alias.name)
                if alias.name == root:
                    aliases.add(alias.asname or root)
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id in aliases):
            out.add(api.get(node.attr, f"{root}.{node.attr}"))
    return {m for m in out if m in modules}


def notebook_tree(path: Path) -> ast.Module:
    """The code cells of a notebook as one syntax tree (IPython magics and shell lines
    dropped)."""
    cells = json.loads(path.read_text())["cells"]
    code = []
    for cell in cells:
        if cell["cell_type"] == "code":
            src = "".join(cell["source"])
            code += [line for line in src.splitlines() if not line.lstrip().startswith(("%", "!"))]
    return ast.parse("\n".join(code))


def _in_skipped(module: str) -> bool:
    parts = module.split(".")
    return len(parts) > 1 and parts[1] == SKIPPED


def paper_path(package: Path, notebooks: list[Path]) -> tuple[set[str], set[str]]:
    """(the modules the paper path reaches, the ``beyond`` modules reached from them):
    the notebooks' imports outside ``beyond``, closed over every import of those modules
    and the packages that hold them."""
    modules, root = package_modules(package), package.name
    api = lazy_api(package)
    graph = {name: imported_modules(ast.parse(path.read_text()), modules, api, root)
             for name, path in modules.items()}
    todo = set()
    for nb in notebooks:
        todo |= {m for m in imported_modules(notebook_tree(nb), modules, api, root)
                 if not _in_skipped(m)}
    reached = set()
    while todo:
        name = todo.pop()
        if name in reached:
            continue
        reached.add(name)
        parents = {".".join(name.split(".")[:i]) for i in range(1, name.count(".") + 1)}
        todo |= (graph[name] | parents) - reached
    return {m for m in reached if not _in_skipped(m)}, {m for m in reached if _in_skipped(m)}


def sizes(package: Path, names: set[str]) -> dict[str, int]:
    """Code lines of ``names`` per sub-package (``(top level)`` for the package's own
    modules, its ``__init__`` included)."""
    modules = package_modules(package)
    packages = {p.name for p in package.iterdir() if (p / "__init__.py").exists()}
    out: dict[str, int] = {}
    for name in sorted(names):
        parts = name.split(".")
        key = parts[1] if len(parts) > 1 and parts[1] in packages else "(top level)"
        out[key] = out.get(key, 0) + code_lines(modules[name].read_text())
    return out


def _table(title: str, counts: dict[str, int]) -> str:
    rows = [f"  {k:<14} {v:>7,}" for k, v in sorted(counts.items())]
    return "\n".join([title, *rows, f"  {'total':<14} {sum(counts.values()):>7,}"])


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("package", nargs="?", type=Path,
                    default=Path(__file__).resolve().parents[1] / "dgt_lib")
    ap.add_argument("--notebooks", type=Path, default=None,
                    help="default: notebooks/ beside the package")
    args = ap.parse_args(argv)
    package = args.package.resolve()
    folder = args.notebooks or package.parent / "notebooks"
    notebooks = sorted(p for p in folder.glob("*.ipynb") if p.name.startswith(PAPER_NOTEBOOKS))
    reached, beyond = paper_path(package, notebooks)
    print(f"{package}: {len(notebooks)} notebooks, {len(reached)} modules on the paper path")
    print(_table("paper path (code lines: no docstrings, comments or blank lines)",
                 sizes(package, reached)))
    print(_table("whole package", sizes(package, set(package_modules(package)))))
    if beyond:
        print("beyond/ reached from the paper path: " + ", ".join(sorted(beyond)))


if __name__ == "__main__":
    main()

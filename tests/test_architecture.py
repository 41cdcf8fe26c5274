"""The library's layout is the paper's pipeline: each sub-package imports only those before
it (docs/ARCHITECTURE.md → Sub-packages), so the data flow can be read from the imports."""

import ast
from pathlib import Path

import dgt_lib

PACKAGE = Path(dgt_lib.__file__).parent
LAYERS = ("core", "world", "perception", "learning", "mapping", "navigation", "beyond",
          "evaluation", "stages")
"""Sub-packages in pipeline order; modules at the top level (viz, rr, report, cli, query)
sit above them all. ``beyond`` holds what goes beyond the paper."""


def _layer(module: str) -> int:
    parts = module.split(".")
    if len(parts) > 1 and parts[1] in LAYERS:
        return LAYERS.index(parts[1])
    return len(LAYERS)  # the top level


def _imports(path: Path) -> set[str]:
    """dgt_lib modules imported by a file (any depth: function-local imports count)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module == "dgt_lib":
                out |= {f"dgt_lib.{a.name}" for a in node.names}
            elif node.module.startswith("dgt_lib."):
                out.add(node.module)
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("dgt_lib.")}
    return out


def _modules() -> dict[str, Path]:
    mods = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        mods[".".join(p for p in parts if p != "__init__")] = path
    return mods


def test_no_module_imports_a_later_stage_of_the_pipeline():
    back_edges = []
    for name, path in _modules().items():
        if name == "dgt_lib":  # the public API re-exports from every layer
            continue
        for target in _imports(path):
            if _layer(target) > _layer(name):
                back_edges.append(f"{name} imports {target}")
    assert back_edges == []


def test_no_relative_imports_so_every_import_names_its_layer():
    relative = [f"{name}" for name, path in _modules().items()
                for node in ast.walk(ast.parse(path.read_text()))
                if isinstance(node, ast.ImportFrom) and node.level > 0]
    assert relative == []


def test_the_sub_packages_are_the_pipeline_stages():
    packages = {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists()}
    assert packages == set(LAYERS) | {"viz"}


def test_module_level_imports_have_no_cycle():
    """Import order is a DAG: no module needs a module that (indirectly) needs it."""
    modules = _modules()
    graph = {}
    for name, path in modules.items():
        deps = set()
        for node in ast.parse(path.read_text()).body:  # module level: what import runs
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                deps |= {m for m in [node.module, *(f"{node.module}.{a.name}"
                                                     for a in node.names)] if m in modules}
        graph[name] = deps - {name, "dgt_lib"}
    cycles, state = [], {}

    def visit(node, stack):
        state[node] = "open"
        for dep in graph[node]:
            if state.get(dep) == "open":
                cycles.append(stack[stack.index(dep):] + [dep])
            elif dep not in state:
                visit(dep, stack + [dep])
        state[node] = "done"

    for name in graph:
        if name not in state:
            visit(name, [name])
    assert cycles == []

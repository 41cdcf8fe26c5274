"""The library's layout is the paper's pipeline: each sub-package imports only those before
it (docs/ARCHITECTURE.md → Sub-packages), so the data flow can be read from the imports."""

import ast
from pathlib import Path

import dgt_lib

PACKAGE = Path(dgt_lib.__file__).parent
LAYERS = ("core", "world", "perception", "learning", "mapping", "navigation", "beyond",
          "evaluation", "stages", "records", "logs")
"""Sub-packages in pipeline order. ``beyond`` holds what goes beyond the paper; above them
all sit :data:`ON_TOP`."""
ON_TOP = ("viz", "exercises", "app")
"""What uses the pipeline, in order: figures and recordings, the notebooks' exercises, the
command-line application (which may use both)."""


def _layer(module: str) -> int:
    parts = module.split(".")
    order = LAYERS + ON_TOP
    if module == "dgt_lib.__version__":  # the package's own version
        return 0
    if len(parts) > 1 and parts[1] in order:
        return order.index(parts[1])
    return len(order)  # the package itself


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


def test_the_sub_packages_are_the_pipeline_stages_and_what_uses_them():
    packages = {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists()}
    assert packages == set(LAYERS) | set(ON_TOP)


def test_every_module_sits_in_a_sub_package():
    """A newcomer finds each module under the part of the kit it belongs to: the top level
    holds only the package's entry points."""
    assert sorted(p.name for p in PACKAGE.glob("*.py")) == ["__init__.py", "__main__.py"]


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


def _import_graph() -> dict[str, set[str]]:
    """Every dgt_lib module → the dgt_lib modules it imports, wherever the import statement
    is (module level, in a function, under ``if TYPE_CHECKING``). ``from a.b import c``
    counts as an import of ``a.b.c`` when that is a module, else of ``a.b``; the root
    package (its lazy public API) is left out."""
    modules = _modules()
    graph = {}
    for name, path in modules.items():
        deps = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                for alias in node.names:
                    sub = f"{node.module}.{alias.name}"
                    deps.add(sub if sub in modules else node.module)
            elif isinstance(node, ast.Import):
                deps |= {a.name for a in node.names}
        graph[name] = {d for d in deps if d in modules} - {name, "dgt_lib"}
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    cycles, state = [], {}

    def visit(node, stack):
        state[node] = "open"
        for dep in sorted(graph[node]):
            if state.get(dep) == "open":
                cycles.append(stack[stack.index(dep):] + [dep])
            elif dep not in state:
                visit(dep, stack + [dep])
        state[node] = "done"

    for name in sorted(graph):
        if name not in state:
            visit(name, [name])
    return cycles


def test_no_import_cycle_of_any_kind():
    """No cycle even through function-local or TYPE_CHECKING imports: each module can be
    read (and tested) with only what it imports understood first."""
    assert _cycles(_import_graph()) == []


MAX_FUNCTION_LINES = 80
MAX_MODULE_LINES = 500
COMPILED = {"njit", "jit", "vectorize", "guvectorize"}
"""numba decorators: a compiled kernel is one loop nest, kept whole for the compiler."""


def _decorator_name(node: ast.expr) -> str:
    node = node.func if isinstance(node, ast.Call) else node
    return node.attr if isinstance(node, ast.Attribute) else getattr(node, "id", "")


def test_no_function_over_80_lines_except_compiled_kernels():
    long = []
    for name, path in _modules().items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                if {_decorator_name(d) for d in node.decorator_list} & COMPILED:
                    continue
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    long.append(f"{name}.{node.name} ({lines})")
    assert long == []


def test_no_module_over_500_lines():
    long = [f"{name} ({n})" for name, path in _modules().items()
            if (n := len(path.read_text().splitlines())) > MAX_MODULE_LINES]
    assert long == []


def _code_size():
    import importlib.util

    path = PACKAGE.parent / "benchmarks" / "code_size.py"
    spec = importlib.util.spec_from_file_location("code_size", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_code_lines_leave_out_docstrings_comments_and_blank_lines():
    source = ('"""Module docstring,\non two lines."""\n\nimport os  # a comment\n\n'
              'def f(x):\n    """Docstring."""\n    # a comment\n    s = """a\nstring"""\n'
              '    return x\n')
    assert _code_size().code_lines(source) == 5  # import, def, s = (two lines), return


def test_the_paper_path_is_counted_and_does_not_reach_beyond():
    """Notebooks 01–09 and every module they reach (any import) stay clear of ``beyond``, of
    the readers of terrain files (a DEM is ``dgt plan``'s, resolved in ``app.plan_one``) and
    of the results report ``dgt reproduce`` writes (``app.report``)."""
    code_size = _code_size()
    notebooks = sorted(p for p in (PACKAGE.parent / "notebooks").glob("*.ipynb")
                       if p.name.startswith(code_size.PAPER_NOTEBOOKS))
    reached, beyond = code_size.paper_path(PACKAGE, notebooks)
    assert len(notebooks) == 9 and beyond == set()
    assert {"dgt_lib.stages.costmaps", "dgt_lib.navigation.planner.search",
            "dgt_lib.core.config"} <= reached
    assert not {"dgt_lib.world.dem", "dgt_lib.app.plan_one", "dgt_lib.app.report"} & reached
    counts = code_size.sizes(PACKAGE, reached)
    assert "beyond" not in counts and sum(counts.values()) > 5000


PAPER_PATH_BUDGET = 12_925
"""Code lines the paper path (notebooks 01–09 and what they reach) may hold: the size it
has, lowered whenever the code shrinks (aim: 8,000)."""
PACKAGE_BUDGET = 17_208
"""Code lines ``dgt_lib`` may hold, lowered whenever the code shrinks (aim: 12,000)."""


def test_the_library_stays_within_its_size_budget():
    """A ratchet: a change that adds code deletes as much elsewhere (docs/ARCHITECTURE.md);
    when the library shrinks, lower the budget to its new size."""
    code_size = _code_size()
    notebooks = sorted(p for p in (PACKAGE.parent / "notebooks").glob("*.ipynb")
                       if p.name.startswith(code_size.PAPER_NOTEBOOKS))
    paper = sum(code_size.sizes(PACKAGE, code_size.paper_path(PACKAGE, notebooks)[0]).values())
    package = sum(code_size.sizes(PACKAGE, set(code_size.package_modules(PACKAGE))).values())
    assert paper <= PAPER_PATH_BUDGET, f"the paper path is {paper:,} code lines"
    assert package <= PACKAGE_BUDGET, f"dgt_lib is {package:,} code lines"

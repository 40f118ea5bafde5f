"""The package's import graph, read from the source with ``ast``: no library module imports the
command line, and no import cycle beyond the known ones (a list that may only shrink).

Module-level imports run when a module is imported: a cycle among them makes the import order
matter and the layers meaningless. Imports inside functions (lazy: numba kernels, the viewer,
optional libraries) run later; they count for the rule on ``ipfit.cli`` (the library must not
depend on the command line at all) and are reported separately for cycles.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = "ipfit"

# Cycles among module-level imports that exist today (none), each the set of modules of one strongly
# connected component. Removing a cycle means deleting its line here; adding one is not allowed.
KNOWN_CYCLES: tuple[frozenset[str], ...] = ()

# Cycles through imports made inside functions, each a lazy call upward; the same rule: it may
# only shrink.
KNOWN_LAZY_CYCLES: tuple[frozenset[str], ...] = (
    # ZeroSet.trimmed() calls trim.trim_zero_set, which takes a ZeroSet: a method for convenience
    frozenset({"ipfit.zeroset.extract", "ipfit.zeroset.trim"}),
)


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(path): path for path in sorted((SRC / PACKAGE).rglob("*.py"))}


def _type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _imports(tree: ast.Module, top_level: bool) -> list[ast.Import | ast.ImportFrom]:
    """Import statements that run: at import time (``top_level``: not in a function), or at
    any time. Imports under ``if TYPE_CHECKING`` never run (annotations only)."""
    found = []

    def visit(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if top_level and isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                continue
            if isinstance(child, ast.If) and _type_checking(child):
                for stmt in child.orelse:
                    visit(ast.Module(body=[stmt], type_ignores=[]))
                continue
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                found.append(child)
            visit(child)

    visit(tree)
    return found


def _targets(module: str, node: ast.Import | ast.ImportFrom, modules: dict[str, Path]) -> set[str]:
    """The package's modules an import statement of ``module`` executes (besides its own
    parent packages, which are always initialised first)."""
    is_package = modules[module].name == "__init__.py"
    if isinstance(node, ast.Import):
        names = [alias.name for alias in node.names]
    else:
        if node.level:
            base = module.split(".") if is_package else module.split(".")[:-1]
            base = base[:len(base) - (node.level - 1)]
            origin = ".".join(base + ([node.module] if node.module else []))
        else:
            origin = node.module or ""
        names = [origin] + [f"{origin}.{alias.name}" for alias in node.names]
    out = set()
    for name in names:
        while name and name not in modules:  # ipfit.io.read_points -> ipfit.io
            name = name.rpartition(".")[0]
        if name.startswith(PACKAGE) and not module.startswith(name + ".") and name != module:
            out.add(name)
    return out


def import_graph(top_level: bool) -> dict[str, set[str]]:
    """Module -> the package's modules it imports (``top_level``: at import time only)."""
    modules = _modules()
    graph = {}
    for module, path in modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        graph[module] = set().union(*(_targets(module, node, modules) for node in _imports(tree, top_level)))
    return graph


def cycles(graph: dict[str, set[str]]) -> list[frozenset[str]]:
    """Strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []

    def connect(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for nxt in sorted(graph.get(node, ())):
            if nxt not in index:
                connect(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in on_stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = set()
            while True:
                top = stack.pop()
                on_stack.discard(top)
                component.add(top)
                if top == node:
                    break
            if len(component) > 1:
                found.append(frozenset(component))

    for node in sorted(graph):
        if node not in index:
            connect(node)
    return found


def _show(component: frozenset[str]) -> str:
    return "{" + ", ".join(sorted(component)) + "}"


@pytest.fixture(scope="module")
def module_graph():
    return import_graph(top_level=True)


@pytest.fixture(scope="module")
def full_graph():
    return import_graph(top_level=False)


def test_the_graph_sees_the_imports_it_must(module_graph, full_graph):
    # the walker itself: relative, absolute, package and submodule imports, lazy ones apart
    assert "ipfit.geometry.distance" in module_graph["ipfit.zeroset.quality"]
    assert "ipfit.zeroset.extract" in module_graph["ipfit.zeroset.trim"]
    assert "ipfit.datasets.loading" in module_graph["ipfit.datasets"]
    assert "ipfit.zeroset.trim" not in module_graph["ipfit.zeroset.extract"]  # in a function and under TYPE_CHECKING
    assert "ipfit.zeroset.trim" in full_graph["ipfit.zeroset.extract"]
    assert "ipfit.degree.adaptive" not in full_graph["ipfit.degree.repair"]  # under TYPE_CHECKING only
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [frozenset("abc")]


def test_no_library_module_imports_the_command_line(full_graph):
    outside = {module: sorted(t for t in targets if t == "ipfit.cli" or t.startswith("ipfit.cli."))
               for module, targets in full_graph.items() if not module.startswith("ipfit.cli")}
    assert {module: found for module, found in outside.items() if found} == {}


def test_no_new_import_cycle(module_graph):
    new = [c for c in cycles(module_graph) if not any(c <= known for known in KNOWN_CYCLES)]
    assert not new, "import cycles among module-level imports: " + "; ".join(map(_show, new))


def test_known_cycles_still_exist(module_graph, full_graph):
    # the exception lists only shrink: a cycle that was broken leaves them
    stale = [known for known in KNOWN_CYCLES if not any(known <= c for c in cycles(module_graph))]
    stale += [known for known in KNOWN_LAZY_CYCLES if not any(known <= c for c in cycles(full_graph))]
    assert not stale, "no longer cycles, remove from KNOWN_CYCLES / KNOWN_LAZY_CYCLES: " + "; ".join(map(_show, stale))


def test_no_new_lazy_import_cycle(full_graph):
    new = [c for c in cycles(full_graph) if not any(c <= known for known in KNOWN_CYCLES + KNOWN_LAZY_CYCLES)]
    assert not new, "import cycles through imports inside functions: " + "; ".join(map(_show, new))


def test_quality_zeroset_trim_form_no_cycle(module_graph, full_graph):
    measured = {"ipfit.zeroset.quality", "ipfit.zeroset.extract", "ipfit.zeroset.trim", "ipfit.geometry.distance"}
    assert not [c for c in cycles(module_graph) if c & measured]
    # quality and the distance engine sit above zeroset and trim even counting lazy imports
    assert not [c for c in cycles(full_graph) if c & {"ipfit.zeroset.quality", "ipfit.geometry.distance"}]


def test_every_public_name_resolves_and_is_listed():
    """`ipfit.__all__` is the public API: in a fresh interpreter (nothing bound yet), every name
    resolves through the lazy map, `dir(ipfit)` lists it, and importing every module of the
    package afterwards rebinds none of them (no module is shadowed by, or shadows, a function)."""
    import os
    import subprocess
    import sys

    code = """
import importlib, pkgutil, sys
import ipfit
assert 'numpy' not in sys.modules, 'import ipfit loaded numpy'
names = list(ipfit.__all__)
assert len(names) == len(set(names)), 'a name twice in __all__'
unlisted = [n for n in names if n not in dir(ipfit)]
assert not unlisted, f'not in dir(ipfit): {unlisted}'
values = {}
for n in names:
    try:
        values[n] = getattr(ipfit, n)
    except (AttributeError, ImportError) as e:
        raise SystemExit(f'ipfit.{n} does not resolve: {e!r}')
unknown = [n for n in dir(ipfit) if not n.startswith('_') and not hasattr(ipfit, n)]
assert not unknown, f'dir(ipfit) lists names that do not resolve: {unknown}'
for info in pkgutil.walk_packages(ipfit.__path__, 'ipfit.'):
    if not info.name.endswith('.__main__'):  # running it is the command line
        importlib.import_module(info.name)
rebound = [n for n in names if getattr(ipfit, n) is not values[n]]
assert not rebound, f'importing the modules rebound: {rebound}'
assert callable(ipfit.quality) and callable(ipfit.refine)
print(len(names))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                         env={**os.environ, "PYTHONPATH": str(SRC)})
    assert out.returncode == 0, out.stderr[-2000:]
    assert int(out.stdout) > 50


def test_the_architecture_page_shows_the_checked_layers():
    """docs/architecture.md's layer list is written from .importlinter (which lint-imports checks
    against the real imports): regenerate it with `python experiments/architecture.py`."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    script = root / "experiments" / "architecture.py"
    assert subprocess.run([sys.executable, str(script), "--check"]).returncode == 0, \
        "docs/architecture.md is stale: run python experiments/architecture.py"


def _imports_ipfit(node: ast.AST) -> bool:
    if isinstance(node, ast.Import):
        return any(alias.name.split(".")[0] == PACKAGE for alias in node.names)
    return isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == PACKAGE


def _puts_src_first(node: ast.stmt) -> bool:
    """``sys.path.insert(0, <an expression naming "src">)`` at module level."""
    if not (isinstance(node, ast.Expr) and isinstance(node.value, ast.Call)):
        return False
    call = node.value
    return (ast.unparse(call.func) == "sys.path.insert" and len(call.args) == 2
            and ast.unparse(call.args[0]) == "0" and "'src'" in ast.unparse(call.args[1]))


@pytest.mark.parametrize("folder", ["experiments", "benchmarks"])
def test_scripts_measure_this_checkout(folder):
    """Every experiment and benchmark that uses ipfit puts this checkout's src/ first on its path
    before its first module-level import of ipfit: a page's numbers and its recorded commit must be
    of the same code, whatever ipfit another virtual environment has installed (session 63's run of
    docs/robust-dense.md measured another checkout's)."""
    missing = []
    for script in sorted((SRC.parent / folder).glob("*.py")):
        tree = ast.parse(script.read_text())
        if not any(_imports_ipfit(node) for node in ast.walk(tree)):
            continue
        guard = next((i for i, node in enumerate(tree.body) if _puts_src_first(node)), None)
        first = next((i for i, node in enumerate(tree.body) if _imports_ipfit(node)), len(tree.body))
        if guard is None or guard > first:
            missing.append(script.name)
    assert not missing, f"put this checkout's src/ first in {folder}/: {', '.join(missing)}"

"""The package's import graph: no circles between modules, and store/ sits below the domain it stores.

The graph is read from the source with :mod:`ast` (every ``import`` statement, including those inside
functions and ``TYPE_CHECKING`` blocks), so a circle hidden behind a local import still counts.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import pytest

PACKAGE = "autosar_cli"
ROOT = Path(__file__).resolve().parents[1] / PACKAGE


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(ROOT.rglob("*.py"))}


def _imported(name: str, path: Path, known: set[str]) -> set[str]:
    """The package modules that module `name` (file `path`) imports."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join([*anchor, base] if base else anchor)
            # `from pkg import mod` imports the submodule; `from mod import name` the module itself
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]
        else:
            continue
        for target in targets:
            # `import a.b.c` names a.b.c; the nearest enclosing module of the package is the edge
            while target and target not in known:
                target = target.rpartition(".")[0]
            if target and target != name and target.startswith(PACKAGE + "."):
                found.add(target)
    return found


@functools.cache
def import_graph() -> dict[str, set[str]]:
    """module -> the package modules it imports."""
    modules = _modules()
    return {name: _imported(name, path, set(modules)) for name, path in modules.items()}


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components of more than one module (each is an import circle)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_circle_finder_finds_a_circle() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert strongly_connected(graph) == [["a", "b", "c"]]
    assert strongly_connected({"a": {"b"}, "b": set()}) == []


def test_graph_reader_sees_local_and_relative_imports() -> None:
    graph = import_graph()
    # a top-level relative import and a function-local absolute import, both known to be in the code
    assert "autosar_cli.ingest.sources" in graph["autosar_cli.ingest.pipeline"]
    assert "autosar_cli.ingest.pipeline" in graph["autosar_cli.cli"]
    assert sum(len(deps) for deps in graph.values()) > 100


def test_no_import_cycles() -> None:
    circles = strongly_connected(import_graph())
    assert not circles, "modules that import each other (directly or round a circle):\n" + "\n".join(
        " <-> ".join(c) for c in circles)


@pytest.mark.parametrize("layer", ["nav", "sar", "evaluate", "sim", "ingest", "cli", "run", "batch"])
def test_store_imports_no_domain_layer(layer: str) -> None:
    graph = import_graph()
    above = f"{PACKAGE}.{layer}"
    offending = sorted(
        f"{src} -> {dst}"
        for src, deps in graph.items()
        for dst in deps
        if src.startswith(f"{PACKAGE}.store") and (dst == above or dst.startswith(above + "."))
    )
    assert not offending, f"store/ imports {layer}: {offending}"

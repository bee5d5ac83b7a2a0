"""The package's layering holds: no import cycle, and no private name used across modules.

Read from the source with ``ast``, function-level imports included (a lazy import
hides a cycle from Python, not from the design).
"""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx

SRC = Path(__file__).resolve().parents[1] / "src"


def _modules() -> dict[str, Path]:
    modules = {}
    for path in SRC.rglob("*.py"):
        parts = list(path.relative_to(SRC).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        modules[".".join(parts)] = path
    return modules


def _imports(name: str, path: Path, modules: dict[str, Path]):
    """(imported module, imported names) for every import statement of a module."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, ()
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1] + ([node.module] if node.module else []))
            for alias in node.names:
                submodule = f"{base}.{alias.name}"
                yield (submodule, ()) if submodule in modules else (base, (alias.name,))


def _nearest_module(target: str, modules: dict[str, Path]) -> str:
    while target and target not in modules:
        target = target.rpartition(".")[0]
    return target


def test_no_import_cycles():
    modules = _modules()
    graph = nx.DiGraph()
    for name, path in modules.items():
        graph.add_node(name)
        for target, _ in _imports(name, path, modules):
            target = _nearest_module(target, modules)
            if target and target != name:
                graph.add_edge(name, target)
    assert graph.number_of_nodes() > 50 and graph.number_of_edges() > 100  # the graph was really read
    cycles = [sorted(c) for c in nx.strongly_connected_components(graph) if len(c) > 1]
    assert cycles == []


def test_no_private_name_imported_across_modules():
    modules = _modules()
    crossings = []
    for name, path in modules.items():
        for target, names in _imports(name, path, modules):
            target = _nearest_module(target, modules)
            if target.startswith("stairenv") and target != name:
                crossings += [f"{name} <- {target}.{n}" for n in names if n.startswith("_") and not n.startswith("__")]
    assert crossings == []

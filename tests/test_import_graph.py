"""The package's layering holds: no import cycle, and no private name used across modules.

Read from the source with ``ast``. An edge is every way one module makes another load:

* import statements anywhere in a module, function-level ones included (a lazy import hides a
  cycle from Python, not from the design);
* names loaded by string: a string constant that is exactly a module name or an entry point
  (``"stairenv.evaluation.sims"``, ``"stairenv.environments.vector:SIMSVectorEnv"``, as given to
  ``importlib.import_module`` or Gymnasium), the constant head of an f-string that builds one
  (``f"stairenv.environments.{module}:{name}Env"``), and the ``entry_point`` of each env preset in
  ``envs/*.toml`` (loaded by ``stairenv.registration``).

Cycles are looked for twice: between modules, and between the packages directly below
``stairenv`` (``stairenv.stories``, ``stairenv.evaluation``, ...; a top-level module is its own
package), where a cycle means two layers each reach into the other.
"""

from __future__ import annotations

import ast
import re
import tomllib
from pathlib import Path

import networkx as nx

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
PRESETS = ROOT / "envs"

# a string that is exactly a dotted stairenv name, optionally ":attribute" (an entry point)
_NAME_STRING = re.compile(r"stairenv(\.[A-Za-z_]\w*)+(:[A-Za-z_][\w.]*)?")
# the constant head of an f-string that builds such a name
_NAME_HEAD = re.compile(r"stairenv(\.[A-Za-z_]\w*)*\.")


def _modules(src: Path = SRC) -> dict[str, Path]:
    modules = {}
    for path in src.rglob("*.py"):
        parts = list(path.relative_to(src).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        modules[".".join(parts)] = path
    return modules


def _named_by_string(node: ast.AST, modules: dict[str, Path]) -> str | None:
    """The module an AST string node names (without ``:attribute``), or None. Only names of
    modules that exist count: ``"stairenv.scene"`` (a file format's name) is no module."""
    named = None
    if isinstance(node, ast.Constant) and isinstance(node.value, str) and _NAME_STRING.fullmatch(node.value):
        named = node.value.partition(":")[0]
    elif isinstance(node, ast.JoinedStr) and node.values:
        head = node.values[0]
        if isinstance(head, ast.Constant) and isinstance(head.value, str) and _NAME_HEAD.fullmatch(head.value):
            named = head.value.rstrip(".")
    return named if named in modules else None


def _imports(name: str, path: Path, modules: dict[str, Path]):
    """(imported module, imported names) for every import statement of a module, and
    (named module, ()) for every module it names by string."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    tree = ast.parse(path.read_text(), str(path))
    f_string_parts = {id(part) for node in ast.walk(tree) if isinstance(node, ast.JoinedStr) for part in node.values}
    for node in ast.walk(tree):
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
        elif id(node) not in f_string_parts and (named := _named_by_string(node, modules)):
            yield named, ()


def _preset_entry_points(presets: Path = PRESETS):
    for path in sorted(presets.glob("*.toml")):
        with path.open("rb") as f:
            entry_point = tomllib.load(f).get("entry_point", "")
        yield entry_point.partition(":")[0]


def _nearest_module(target: str, modules: dict[str, Path]) -> str:
    while target and target not in modules:
        target = target.rpartition(".")[0]
    return target


def import_graph(src: Path = SRC, presets: Path | None = PRESETS, loader: str = "stairenv.registration") -> nx.DiGraph:
    """Module -> module it makes load (imports and names by string); presets' entry points are
    edges of ``loader``."""
    modules = _modules(src)
    graph = nx.DiGraph()
    for name, path in modules.items():
        graph.add_node(name)
        targets = [target for target, _ in _imports(name, path, modules)]
        if name == loader and presets is not None:
            targets += _preset_entry_points(presets)
        for target in targets:
            target = _nearest_module(target, modules)
            if target and target != name:
                graph.add_edge(name, target)
    return graph


def package_of(module: str) -> str:
    """``stairenv.stories.machine`` -> ``stairenv.stories``; ``stairenv`` itself stays."""
    return ".".join(module.split(".")[:2])


def package_graph(graph: nx.DiGraph) -> nx.DiGraph:
    packages = nx.DiGraph()
    for a, b in graph.edges:
        if package_of(a) != package_of(b):
            packages.add_edge(package_of(a), package_of(b))
    return packages


def cycles(graph: nx.DiGraph) -> list[list[str]]:
    return sorted(sorted(c) for c in nx.strongly_connected_components(graph) if len(c) > 1)


def test_no_import_cycles():
    graph = import_graph()
    assert graph.number_of_nodes() > 50 and graph.number_of_edges() > 100  # the graph was really read
    # the name-string edges were read too: the evaluators by name, the env classes of the presets
    assert graph.has_edge("stairenv.evaluation", "stairenv.evaluation.sims")
    assert graph.has_edge("stairenv.registration", "stairenv.environments.interlevel")
    assert cycles(graph) == []


def test_no_import_cycles_between_packages():
    packages = package_graph(import_graph())
    assert packages.has_edge("stairenv.evaluation", "stairenv.stories")  # the graph was really read
    assert cycles(packages) == []


def test_cycles_through_lazy_imports_and_name_strings_are_found(tmp_path):
    """The old cycle between ``stories`` and ``evaluation``, in miniature: a function-level import
    one way, a top-level import back, and the link inside ``evaluation`` only a string."""
    files = {
        "stairenv/__init__.py": "",
        "stairenv/stories/__init__.py": "from stairenv.stories.machine import run\n",
        "stairenv/stories/machine.py": "def run():\n    from stairenv.evaluation import load_policy\n",
        "stairenv/evaluation/__init__.py": (
            "import importlib\n"
            "EVALUATORS = {'sims': 'stairenv.evaluation.sims'}\n"
            "def load_policy():\n    pass\n"
            "def evaluator(family):\n    return importlib.import_module(EVALUATORS[family])\n"
        ),
        "stairenv/evaluation/sims.py": "from stairenv.stories import run\n",
        "stairenv/registration.py": "ENTRY = {m: f'stairenv.environments.{m}:Env' for m in ('a',)}\n",
        "stairenv/environments/__init__.py": "import stairenv.registration\n",
        "stairenv/environments/a.py": "",
        "envs/A-v0.toml": 'id = "A-v0"\nentry_point = "stairenv.environments.a:AEnv"\n',
    }
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    graph = import_graph(tmp_path, presets=None)
    assert graph.has_edge("stairenv.stories.machine", "stairenv.evaluation")    # function-level import
    assert graph.has_edge("stairenv.evaluation", "stairenv.evaluation.sims")   # name string
    assert graph.has_edge("stairenv.registration", "stairenv.environments")    # f-string head
    assert cycles(graph) == [
        ["stairenv.environments", "stairenv.registration"],
        ["stairenv.evaluation", "stairenv.evaluation.sims", "stairenv.stories", "stairenv.stories.machine"],
    ]
    assert cycles(package_graph(graph)) == [["stairenv.environments", "stairenv.registration"],
                                            ["stairenv.evaluation", "stairenv.stories"]]
    # the preset's entry point is an edge of the module that loads the presets
    with_presets = import_graph(tmp_path, presets=tmp_path / "envs")
    assert with_presets.has_edge("stairenv.registration", "stairenv.environments.a")
    # without the lazy import the cycle is gone (the check is not merely finding every string)
    (tmp_path / "stairenv/stories/machine.py").write_text("def run():\n    pass\n")
    assert cycles(import_graph(tmp_path, presets=None)) == [["stairenv.environments", "stairenv.registration"]]


def test_no_private_name_imported_across_modules():
    modules = _modules()
    crossings = []
    for name, path in modules.items():
        for target, names in _imports(name, path, modules):
            target = _nearest_module(target, modules)
            if target.startswith("stairenv") and target != name:
                crossings += [f"{name} <- {target}.{n}" for n in names if n.startswith("_") and not n.startswith("__")]
    assert crossings == []

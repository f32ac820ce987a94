"""The package's layout: engine, scenes, analyses, checks and runs in their own folders, and no import cycle.

The import graph is read from the source (every ``from jaxbill... import``,
function bodies included), not from what Python happened to import, so a
cycle hidden behind a lazy import fails too.
"""

from __future__ import annotations

import ast
import pathlib

import pytest

jb = pytest.importorskip("jaxbill")

PACKAGE = pathlib.Path(jb.__file__).parent
FOLDERS = {"_engine", "_scenes", "_analysis", "_check", "_runs"}
# The user-facing modules that stay at the top: the namespace, the pictures, the command,
# and the studies built on the library (a public package: each study imported by name).
TOP_LEVEL = {"__init__", "plotting", "cli", "_figures", "_explorer", "studies"}


def _module_name(path: pathlib.Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in PACKAGE.rglob("*.py")}


def _imports(path: pathlib.Path) -> set[str]:
    """The ``jaxbill`` modules that ``path`` imports, anywhere in the file."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("jaxbill"):
            assert node.level == 0, f"{path}: relative import of {node.module}"
            for alias in node.names:
                submodule = f"{node.module}.{alias.name}"
                found.add(submodule if submodule in MODULES else node.module)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("jaxbill"))
    return found


def test_every_module_lives_in_its_folder():
    misplaced = [
        name
        for name in MODULES
        if name != "jaxbill" and name.split(".")[1] not in FOLDERS and name.split(".")[1] not in TOP_LEVEL
    ]
    assert not misplaced, f"modules outside engine/scenes/analysis/check/runs and the top-level UI: {misplaced}"


def test_the_engine_knows_no_scene_and_no_analysis():
    """The engine is what every scene plugs into: it may not import a scene, an analysis or a check."""
    offending = {
        (name, imported)
        for name, path in MODULES.items()
        if name.startswith("jaxbill._engine")
        for imported in _imports(path)
        if imported.startswith(("jaxbill._scenes.", "jaxbill._analysis", "jaxbill._check"))
        and imported != "jaxbill._scenes.protocols"
    }
    assert not offending, offending


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle of ``graph`` (module -> modules it imports), as a closed path, or None."""
    state: dict[str, str] = {}

    def visit(module, trail):
        if state.get(module) == "done":
            return None
        if state.get(module) == "open":
            return trail[trail.index(module) :] + [module]
        state[module] = "open"
        for imported in sorted(graph.get(module, ())):
            cycle = visit(imported, trail + [module])
            if cycle:
                return cycle
        state[module] = "done"
        return None

    for module in sorted(graph):
        cycle = visit(module, [])
        if cycle:
            return cycle
    return None


def test_no_import_cycles_in_the_package():
    """No module imports one that imports it back, directly or not (imports inside functions count).

    The namespace ``jaxbill`` and the folders' ``__init__`` files are left out:
    they hold no code that imports back.
    """
    packages = {name for name, path in MODULES.items() if path.name == "__init__.py"}
    graph = {name: _imports(path) - packages for name, path in MODULES.items() if name not in packages}
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def test_the_cycle_finder_finds_cycles():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None

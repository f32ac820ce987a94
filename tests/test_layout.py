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
    return {imported for imported, _ in _imported_names(path)}


def _imported_names(path: pathlib.Path) -> set[tuple[str, str | None]]:
    """``(module, name)`` for each ``from jaxbill... import name`` in ``path`` (``name`` None where the
    import is of a module), anywhere in the file."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("jaxbill"):
            assert node.level == 0, f"{path}: relative import of {node.module}"
            for alias in node.names:
                submodule = f"{node.module}.{alias.name}"
                found.add((submodule, None) if submodule in MODULES else (node.module, alias.name))
        elif isinstance(node, ast.Import):
            found.update((a.name, None) for a in node.names if a.name.startswith("jaxbill"))
    return found


# The layers, lowest first: a module imports from its own layer or a lower one, never from a
# higher one or a sibling (the analyses, the checker and the runs know nothing of each other).
LAYERS = (
    {"_engine"},
    {"_scenes"},
    {"_analysis", "_check", "_runs"},
    {"plotting", "_explorer", "studies", "_figures"},
    {"jaxbill"},  # the namespace
    {"cli"},  # the command, the one module above the namespace
)


def _layer_of(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "jaxbill"


def layer_violations(graph: dict[str, set[str]]) -> set[tuple[str, str]]:
    """Every import of ``graph`` (module -> modules it imports) that points up, or sideways between the
    folders of one layer; the top-level user modules (``plotting``, the explorer, the figures, the
    studies) may use each other."""
    rank = {folder: position for position, layer in enumerate(LAYERS) for folder in layer}
    bad = set()
    for module, imported in graph.items():
        own = _layer_of(module)
        for target in imported:
            other = _layer_of(target)
            if rank[other] > rank[own] or (rank[other] == rank[own] == 2 and other != own):
                bad.add((module, target))
    return bad


def private_imports(imports: dict[str, set[tuple[str, str | None]]]) -> set[tuple[str, str]]:
    """Every ``from module import _name`` across modules: a private name stays in its module."""
    return {
        (module, f"{source}.{name}")
        for module, names in imports.items()
        for source, name in names
        if name is not None and name.startswith("_") and not name.startswith("__")
    }


def test_every_module_lives_in_its_folder():
    misplaced = [
        name
        for name in MODULES
        if name != "jaxbill" and name.split(".")[1] not in FOLDERS and name.split(".")[1] not in TOP_LEVEL
    ]
    assert not misplaced, f"modules outside engine/scenes/analysis/check/runs and the top-level UI: {misplaced}"


def test_the_engine_knows_no_scene_and_no_analysis():
    """The engine is what every scene plugs into: it owns the interface it calls (``_engine.interface``) and
    imports no scene, analysis, check or run."""
    offending = {
        (name, imported)
        for name, path in MODULES.items()
        if name.startswith("jaxbill._engine")
        for imported in _imports(path)
        if imported.startswith(("jaxbill._scenes", "jaxbill._analysis", "jaxbill._check", "jaxbill._runs"))
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

    The namespace ``jaxbill`` is a node like any module (a study that did ``import jaxbill`` would close a
    cycle through it); the folders' ``__init__`` files, which hold only docstrings, are left out.
    """
    packages = {name for name, path in MODULES.items() if path.name == "__init__.py" and name != "jaxbill"}
    graph = {name: _imports(path) - packages for name, path in MODULES.items() if name not in packages}
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def test_layers_only_point_down():
    """The engine, then the scenes, then the analyses, the checker and the runs (which know nothing of one
    another), then the pictures, the explorer and the studies, then the namespace, then the command."""
    packages = {name for name, path in MODULES.items() if path.name == "__init__.py" and name != "jaxbill"}
    graph = {name: _imports(path) - packages for name, path in MODULES.items() if name not in packages}
    assert not layer_violations(graph), sorted(layer_violations(graph))


def test_no_private_name_crosses_a_module():
    imports = {name: _imported_names(path) for name, path in MODULES.items()}
    assert not private_imports(imports), sorted(private_imports(imports))


def kind_readings(source: str) -> list[int]:
    """The lines of ``source`` that read a scene through its ``kind`` string (``scene.kind == "rotor"``,
    ``{...}[scene.kind]``) where a declared capability (``body_turns``, ``body_is_point``) says what it means."""

    def scene_kind(node) -> bool:
        return isinstance(node, ast.Attribute) and node.attr == "kind" and "scene" in ast.unparse(node.value)

    lines = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            if any(scene_kind(side) for side in sides) and any(
                isinstance(side, ast.Constant) and isinstance(side.value, str) for side in sides
            ):
                lines.append(node.lineno)
        elif isinstance(node, ast.Subscript) and scene_kind(node.slice):
            lines.append(node.lineno)
    return lines


def test_above_the_scenes_nothing_reads_a_kind_string():
    """The analyses, checks, runs and pictures ask a scene what its body does, not which kind it is."""
    above = {name: path for name, path in MODULES.items() if _layer_of(name) not in ("_engine", "_scenes")}
    found = {name: kind_readings(path.read_text()) for name, path in above.items()}
    assert not {name: lines for name, lines in found.items() if lines}


def test_each_rule_fails_on_a_violation():
    """Each rule, on a synthetic package that breaks it."""
    assert layer_violations({"jaxbill._engine.step": {"jaxbill._scenes.protocols"}})  # up
    assert layer_violations({"jaxbill._scenes.circle.scene": {"jaxbill._check.checker"}})  # up
    assert layer_violations({"jaxbill._analysis.chaos": {"jaxbill._runs.streaming"}})  # sideways
    assert layer_violations({"jaxbill.studies.small_stick": {"jaxbill"}})  # the namespace, from below it
    assert not layer_violations({"jaxbill._analysis.chaos": {"jaxbill._scenes.protocols", "jaxbill._engine.step"}})
    assert not layer_violations({"jaxbill.cli": {"jaxbill", "jaxbill._explorer"}})
    assert private_imports({"jaxbill._analysis.chaos": {("jaxbill._engine.collision", "_poison")}})
    assert not private_imports({"jaxbill.cli": {("jaxbill", "__version__"), ("jaxbill._engine.collision", "orbit")}})
    assert find_cycle({"jaxbill": {"jaxbill.studies.arnold_web"}, "jaxbill.studies.arnold_web": {"jaxbill"}})
    assert kind_readings('if scene.kind == "rotor":\n    pass') == [1]
    assert kind_readings('size = {"rotor": 4, "lens": 3}[scene.kind]') == [1]
    assert not kind_readings('if scene.body_turns and record.kind == "final":\n    pass')


def test_the_cycle_finder_finds_cycles():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None


def _type_checking_imports(path: pathlib.Path) -> dict[str, tuple[str, ...]]:
    """``{module: names}`` of the ``from ... import`` lines under ``if TYPE_CHECKING:`` in ``path``."""
    found = {}
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            for line in node.body:
                if isinstance(line, ast.ImportFrom) and line.module:
                    found[line.module] = tuple(alias.name for alias in line.names)
    return found


def test_the_namespace_loads_what_it_declares():
    """``jaxbill`` loads its public names on first use, from a table of modules; the same names are
    imported for type checkers and the API reference, and listed in ``__all__``: all three agree, and
    each name is found where the table says."""
    import importlib

    import jaxbill

    declared = _type_checking_imports(PACKAGE / "__init__.py")
    assert declared == jaxbill._PUBLIC
    loaded = {name for names in jaxbill._PUBLIC.values() for name in names}
    assert sorted(jaxbill.__all__) == sorted(loaded | {"backend_settings"})
    for module, names in jaxbill._PUBLIC.items():
        for name in names:
            public, defined = getattr(jaxbill, name), getattr(importlib.import_module(module), name)
            # the tests' shape checks (conftest.py) wrap some public functions
            assert defined in (public, getattr(public, "__wrapped__", None))
    with pytest.raises(AttributeError, match="no attribute 'orbitt'"):
        jaxbill.orbitt  # noqa: B018

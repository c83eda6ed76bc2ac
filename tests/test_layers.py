"""The layers point one way. Read from the source, so a new import that breaks a rule fails here.

* Every module of ``armstereo``, ``drivers`` and ``robot_models`` belongs to one layer of
  :data:`LAYERS` (lowest first) and imports only from its own layer or lower ones: no
  up-running import. The same order, with what each layer holds, is in docs/architecture.md.
* No import cycle, between modules or between packages.
* ``drivers`` depends on ``armstereo``, never the reverse (only the backend registry reaches into
  ``drivers``, lazily and by name), and no library module imports the command line.

Every import counts, at the top of a module, under ``TYPE_CHECKING`` or inside a function: a lazy
import still ties the two modules. The one exception is the root ``armstereo/__init__.py``, the
package's face: importing any submodule loads it anyway, so an import of it is no edge, and its
own import (``reconstruct_views``) must stay lazy.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable
from pathlib import Path

import pytest

from tests.support import ROOT

REGISTRY = ROOT / "armstereo" / "backends.py"
ROOT_PACKAGE = "armstereo"
SOURCE_PACKAGES = ("armstereo", "drivers", "robot_models")

# Lowest first. A name is a module or a package (then it holds every module under it). Only
# imports to the same layer or below are allowed.
LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("basics", ("armstereo.errors", "armstereo.frame", "armstereo.clock", "armstereo.flags",
                "armstereo.validate", "armstereo.transforms", "armstereo.camera_model",
                "armstereo.io", "armstereo.camera_settings", "robot_models")),
    ("models of the arm, the camera and the truth",
     ("armstereo.mount", "armstereo.photometric", "armstereo.devices", "armstereo.robot",
      "armstereo.kinematics", "armstereo.evaluation")),
    ("recordings", ("armstereo.recording",)),
    ("geometry from images", ("armstereo.reconstruct", "armstereo.calibration",
                              "armstereo.scene", "armstereo.epipolar")),
    ("workflows", ("armstereo.capture", "armstereo.fusion")),
    ("drivers", ("drivers",)),
    ("backend registry", ("armstereo.backends",)),
    ("applications and bridges", ("armstereo.apps", "armstereo.ros2")),
    ("command line", ("armstereo.cli", "armstereo.__main__")),
)


# ---------------------------------------------------------------------------- the import graph
def module_files() -> dict[str, Path]:
    """Dotted module name -> file, for every module of the source packages."""
    out = {}
    for package in SOURCE_PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            out[".".join(parts)] = path
    return out


MODULES = module_files()


def imported_modules(path: Path) -> list[tuple[int, str]]:
    """(line, module) of every absolute import statement in ``path``, nested ones included."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.append((node.lineno, node.module))
    return out


def imported_source_modules(name: str, path: Path,
                            modules: dict[str, Path]) -> list[tuple[int, str]]:
    """(line, module) of every module of ``modules`` that ``name`` imports, relative imports and
    ``from package import submodule`` resolved; imports of the root package are left out."""
    out = []
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        targets = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(up + ([node.module] if node.module else []))
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base
                       for a in node.names]
        for target in targets:
            while target and target not in modules:
                target = target.rpartition(".")[0]
            if target and target not in (name, ROOT_PACKAGE):
                out.append((node.lineno, target))
    return out


def import_graph(modules: dict[str, Path]) -> dict[str, dict[str, int]]:
    """module -> {imported module: first line}."""
    graph: dict[str, dict[str, int]] = {}
    for name, path in modules.items():
        edges: dict[str, int] = {}
        for line, target in imported_source_modules(name, path, modules):
            edges.setdefault(target, line)
        graph[name] = edges
    return graph


GRAPH = import_graph(MODULES)


def layer_of(module: str, layers=LAYERS) -> int | None:
    """Index of the layer holding ``module`` (the longest name that contains it decides)."""
    best, best_len = None, -1
    for i, (_, names) in enumerate(layers):
        for n in names:
            if (module == n or module.startswith(n + ".")) and len(n) > best_len:
                best, best_len = i, len(n)
    return best


def up_running(graph: dict[str, dict[str, int]], layers=LAYERS) -> list[str]:
    """Every import from a lower layer to a higher one, as 'a (layer) line N -> b (layer)'."""
    bad = []
    for a, edges in sorted(graph.items()):
        for b, line in sorted(edges.items()):
            la, lb = layer_of(a, layers), layer_of(b, layers)
            if la is not None and lb is not None and lb > la:
                bad.append(f"{a} ({layers[la][0]}) line {line} -> {b} ({layers[lb][0]})")
    return bad


def cycles(graph: dict[str, Iterable[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
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


def package_of(module: str) -> str:
    """The package a module is counted in for the package cycles: ``armstereo.<pkg>``,
    ``drivers.<pkg>`` or the top-level module itself."""
    parts = module.split(".")
    return ".".join(parts[:2])


def package_graph(graph: dict[str, dict[str, int]]) -> dict[str, set[str]]:
    out: dict[str, set[str]] = {}
    for a, edges in graph.items():
        pa = package_of(a)
        out.setdefault(pa, set()).update(package_of(b) for b in edges if package_of(b) != pa)
    return out


# ---------------------------------------------------------------------------- the checks' own test
def test_the_scan_sees_the_package():
    assert len(MODULES) > 100
    assert GRAPH["armstereo.mount"].keys() >= {"armstereo.errors", "armstereo.transforms"}
    # nested and TYPE_CHECKING imports count: the lazy one in the registry's users, and
    # ``from armstereo.recording import schemas`` resolves to the submodule
    assert "armstereo.recording.schemas" in GRAPH["armstereo.recording.reader"]
    assert "armstereo.robot.pinocchio_dh" in GRAPH["armstereo.robot.arm_model"]


def test_the_checks_find_what_they_look_for():
    layers = (("low", ("a",)), ("high", ("b",)))
    assert up_running({"a.x": {"b.y": 3}, "b.y": {}}, layers) == [
        "a.x (low) line 3 -> b.y (high)"]
    assert up_running({"b.y": {"a.x": 3}, "a.x": {}}, layers) == []
    assert cycles({"p": {"q"}, "q": {"r"}, "r": {"p"}, "s": {"p"}}) == [["p", "q", "r"]]
    assert cycles({"p": {"q"}, "q": set()}) == []
    assert layer_of("armstereo.recording.reader") == layer_of("armstereo.recording")
    assert layer_of("armstereo.cli.main") == len(LAYERS) - 1


# ---------------------------------------------------------------------------- the rules
def test_every_module_has_a_layer():
    assert not [m for m in MODULES if m != ROOT_PACKAGE and layer_of(m) is None], \
        "place the new package in LAYERS (tests/test_layers.py) and docs/architecture.md"


def test_no_import_runs_up_the_layers():
    bad = up_running(GRAPH)
    assert not bad, "imports from a lower layer to a higher one:\n" + "\n".join(bad)


def test_no_import_cycle_between_modules():
    assert not cycles(GRAPH)


def test_no_import_cycle_between_packages():
    assert not cycles(package_graph(GRAPH))


def test_the_root_package_imports_only_lazily():
    tree = ast.parse((ROOT / "armstereo" / "__init__.py").read_text())
    top = [n for n in tree.body if isinstance(n, ast.Import | ast.ImportFrom)
           and (n.module if isinstance(n, ast.ImportFrom) else n.names[0].name or "")
           .startswith("armstereo")]
    assert not top


def library_files() -> list[Path]:
    return sorted((ROOT / "armstereo").rglob("*.py"))


@pytest.mark.parametrize("path", library_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_armstereo_never_imports_drivers(path):
    if path == REGISTRY:
        return
    bad = [f"line {n}: {m}" for n, m in imported_modules(path)
           if m == "drivers" or m.startswith("drivers.")]
    assert not bad, f"{path.relative_to(ROOT)} imports drivers ({', '.join(bad)}); go through " \
                    "armstereo.backends"


def test_the_registry_imports_drivers_only_lazily():
    top_level = [n for n in ast.parse(REGISTRY.read_text()).body
                 if isinstance(n, ast.Import | ast.ImportFrom)]
    names = [a.name for n in top_level if isinstance(n, ast.Import) for a in n.names]
    names += [n.module for n in top_level if isinstance(n, ast.ImportFrom) and n.module]
    assert not [m for m in names if m.startswith("drivers")]


# ``python -m armstereo`` is the command line's own entry point.
@pytest.mark.parametrize("path", [p for p in library_files()
                                  if "cli" not in p.parts and p.name != "__main__.py"],
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_library_never_imports_the_cli(path):
    bad = [f"line {n}: {m}" for n, m in imported_modules(path) if m.startswith("armstereo.cli")]
    assert not bad, f"{path.relative_to(ROOT)} imports the CLI ({', '.join(bad)})"

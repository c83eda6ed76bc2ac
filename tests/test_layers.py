"""The layers point one way: ``drivers`` depends on ``armstereo``, never the reverse (only the
backend registry reaches into ``drivers``, lazily and by name), and no library module imports
the command line. Read from the source, so a new import that breaks the rule fails here."""

import ast
from pathlib import Path

import pytest

from tests.support import ROOT

REGISTRY = ROOT / "armstereo" / "backends.py"


def imported_modules(path: Path) -> list[tuple[int, str]]:
    """(line, module) of every import statement in ``path``, nested ones included."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.append((node.lineno, node.module))
    return out


def library_files() -> list[Path]:
    return sorted((ROOT / "armstereo").rglob("*.py"))


def test_the_scan_sees_the_package():
    assert len(library_files()) > 40
    assert any(m == "armstereo.errors" for _, m in imported_modules(ROOT / "armstereo/mount.py"))


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

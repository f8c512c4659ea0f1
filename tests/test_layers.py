"""The three packages import in one direction only: analysis <- planning <- rig."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FORBIDDEN = {"analysis": {"planning", "rig"}, "planning": {"rig"}, "rig": set()}


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module.split(".")[0])
    return out


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_package_imports_only_downwards(package: str) -> None:
    bad = []
    for path in sorted((ROOT / package).rglob("*.py")):
        for mod in _imports(path) & FORBIDDEN[package]:
            bad.append(f"{path.relative_to(ROOT)} imports {mod}")
    assert not bad, "layering broken:\n" + "\n".join(bad)


def test_no_runtime_code_imports_tests() -> None:
    bad = [
        str(p.relative_to(ROOT))
        for pkg in FORBIDDEN
        for p in (ROOT / pkg).rglob("*.py")
        if "tests" in _imports(p) or "conftest" in _imports(p)
    ]
    assert not bad

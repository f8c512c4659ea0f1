"""The house's import rules, read from the code's own imports (AST, every import: top level,
inside functions and under TYPE_CHECKING alike).

- The three packages import in one direction only: analysis <- planning <- rig.
- Inside a package, each subpackage imports only the subpackages listed for it below (floors:
  a subpackage imports from lower floors only). A lower package may be imported whole.
- No module imports another subpackage's private (``_name``) module.
- No import cycle between modules at all.
"""

from __future__ import annotations

import ast
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("analysis", "planning", "rig")
FORBIDDEN = {"analysis": {"planning", "rig"}, "planning": {"rig"}, "rig": set()}

# Per subpackage (or top-level module): the units of its own package it may import.
MAY_IMPORT: dict[str, set[str]] = {
    "analysis": {"analysis.errors"},  # the package face: the version only
    "analysis.errors": set(),
    "analysis.validation": {"analysis.errors"},
    "analysis.config": {"analysis.errors", "analysis.validation"},
    "analysis.runs": {"analysis.errors", "analysis.config"},
    "analysis.forces": {"analysis.errors", "analysis.config", "analysis.runs"},
    "analysis.modal": {
        "analysis.errors",
        "analysis.validation",
        "analysis.config",
        "analysis.runs",
    },
    "analysis.rules": {
        "analysis.errors",
        "analysis.validation",
        "analysis.config",
        "analysis.runs",
        "analysis.forces",
    },
    "analysis.chatter": {"analysis.errors", "analysis.runs"},
    "analysis.identify": {
        "analysis",
        "analysis.errors",
        "analysis.config",
        "analysis.runs",
        "analysis.forces",
        "analysis.modal",
    },
    "analysis.stability": {"analysis.errors", "analysis.validation", "analysis.modal"},
    "analysis.catalog": {
        "analysis",
        "analysis.errors",
        "analysis.validation",
        "analysis.config",
        "analysis.runs",
        "analysis.identify",
    },
    "planning": set(),
    "planning.errors": set(),
    "planning.nc": {"planning.errors"},
    "planning.stock": {"planning.errors", "planning.nc"},
    "planning.feed": {"planning.errors", "planning.nc", "planning.stock"},
    "planning.surface": {"planning.errors", "planning.nc", "planning.stock"},
    "planning.rough": {"planning.errors", "planning.nc", "planning.stock", "planning.surface"},
    "planning.orient": {"planning.errors", "planning.nc", "planning.stock", "planning.surface"},
    "planning.limits": {
        "planning.errors",
        "planning.nc",
        "planning.stock",
        "planning.feed",
        "planning.rough",
    },
    "rig": set(),
    "rig.errors": set(),
    "rig.daq": {"rig.errors"},
    "rig.dnc": {"rig.errors"},
    "rig.log": {"rig.errors", "rig.daq"},
    "rig.sim": {"rig.errors", "rig.daq", "rig.dnc", "rig.log"},
    "rig.adaptive": {"rig.errors", "rig.daq", "rig.dnc"},
    "rig.campaign": {"rig.errors", "rig.daq", "rig.dnc", "rig.log", "rig.sim", "rig.adaptive"},
    "rig.report": {"rig.errors", "rig.daq", "rig.log", "rig.campaign", "rig.adaptive"},
    "rig.console": {"rig.errors", "rig.daq", "rig.dnc", "rig.adaptive", "rig.campaign"},
    "rig.cli": {
        "rig",
        "rig.errors",
        "rig.daq",
        "rig.dnc",
        "rig.log",
        "rig.sim",
        "rig.campaign",
        "rig.report",
        "rig.console",
        "rig.adaptive",
    },
}


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@cache
def _modules() -> dict[str, Path]:
    return {_module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


def _resolve(name: str) -> str:
    """The module an import names: ``a.b`` itself, or its nearest enclosing module."""
    mods = _modules()
    while name and name not in mods:
        name = name.rpartition(".")[0]
    return name


@cache
def _imports(module: str) -> frozenset[str]:
    """Modules of this house that ``module`` imports (``from P import x`` counts as P.x when x
    is a module, else as P; a face's ``_LAZY`` table counts as importing its modules)."""
    path = _modules()[module]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [f"{node.module}.{a.name}" for a in node.names]
        if isinstance(node, ast.Assign) and any(
            isinstance(tg, ast.Name) and tg.id == "_LAZY" for tg in node.targets
        ):  # a face's modules loaded on first use (PEP 562 __getattr__): imports all the same
            names = [k.value for k in node.value.keys if isinstance(k, ast.Constant)]
        for n in names:
            if n.split(".")[0] in PACKAGES:
                out.add(_resolve(n))
    out.discard(module)
    return frozenset(out)


def _unit(module: str) -> str:
    """The subpackage (or top-level module) a module belongs to: ``planning.nc.arcs`` ->
    ``planning.nc``; ``analysis.config`` -> itself; ``rig`` -> ``rig``."""
    return ".".join(module.split(".")[:2])


def _raw_imports(path: Path) -> set[str]:
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
        for mod in _raw_imports(path) & FORBIDDEN[package]:
            bad.append(f"{path.relative_to(ROOT)} imports {mod}")
    assert not bad, "layering broken:\n" + "\n".join(bad)


def test_every_subpackage_has_a_rule() -> None:
    units = {_unit(m) for m in _modules()}
    assert units == set(MAY_IMPORT), (
        f"no rule for {sorted(units - set(MAY_IMPORT))}; "
        f"rules for missing {sorted(set(MAY_IMPORT) - units)}"
    )


@pytest.mark.parametrize("unit", sorted(MAY_IMPORT))
def test_subpackage_imports_only_its_lower_floors(unit: str) -> None:
    package = unit.split(".")[0]
    bad = []
    for mod in sorted(m for m in _modules() if _unit(m) == unit):
        for target in sorted(_imports(mod)):
            t_unit = _unit(target)
            if t_unit.split(".")[0] != package or t_unit == unit:
                continue
            if t_unit not in MAY_IMPORT[unit]:
                bad.append(f"{mod} imports {target} ({t_unit} is not below {unit})")
    assert not bad, "\n".join(bad)


def test_no_import_of_another_subpackages_private_module() -> None:
    bad = []
    for mod in sorted(_modules()):
        for target in sorted(_imports(mod)):
            private = any(p.startswith("_") for p in target.split(".")[2:])
            if private and _unit(target) != _unit(mod):
                bad.append(f"{mod} imports {target}")
    assert not bad, "private modules used across subpackages:\n" + "\n".join(bad)


def _cycles(graph: dict[str, list[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, 0)]
        while work:
            node, i = work.pop()
            if i == 0:
                index[node] = low[node] = counter
                counter += 1
                stack.append(node)
                on_stack.add(node)
            for j in range(i, len(graph[node])):
                nxt = graph[node][j]
                if nxt not in index:
                    work.append((node, j + 1))
                    work.append((nxt, 0))
                    break
                if nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
            else:
                if low[node] == index[node]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        comp.append(w)
                        if w == node:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
                if work:
                    parent = work[-1][0]
                    low[parent] = min(low[parent], low[node])
    return out


def test_no_import_cycle() -> None:
    cycles = _cycles({m: sorted(_imports(m)) for m in _modules()})
    assert not cycles, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in cycles)


def test_the_cycle_check_finds_cycles() -> None:
    graph = {"a": ["b"], "b": ["c"], "c": ["a", "d"], "d": [], "e": ["f"], "f": ["e"]}
    assert sorted(_cycles(graph)) == [["a", "b", "c"], ["e", "f"]]
    assert _cycles({"a": ["b"], "b": [], "c": ["a"]}) == []


def test_no_runtime_code_imports_tests() -> None:
    bad = [
        str(p.relative_to(ROOT))
        for pkg in FORBIDDEN
        for p in (ROOT / pkg).rglob("*.py")
        if "tests" in _raw_imports(p) or "conftest" in _raw_imports(p)
    ]
    assert not bad


def test_independent_facemill_simulator_shares_no_model_code() -> None:
    """rig/sim/facemill_independent.py judges seed 003's model and fit (issue 33): neither it
    nor anything it imports, however indirectly, may import analysis.forces or
    analysis.identify."""
    seen: set[str] = set()
    todo = ["rig.sim.facemill_independent"]
    while todo:
        mod = todo.pop()
        for target in _imports(mod):
            if target not in seen:
                seen.add(target)
                todo.append(target)
    shared = sorted(m for m in seen if _unit(m) in ("analysis.forces", "analysis.identify"))
    assert not shared, shared

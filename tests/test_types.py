"""Typed contracts: mypy strict on analysis/, planning/ and rig/ but for the rig modules not
strict yet (mypy's defaults there), no new error (the ``[tool.mypy]`` section of pyproject.toml;
rig's files with errors left within a per-file ceiling), no ``Any`` in the signature of a
public function there, and no bare dict
returned across a package face of analysis/, planning/ or rig/ (nor ``Any`` in rig's public
signatures) but for the allow-lists, each entry with why.

The mypy run uses the cache in ``.mypy_cache`` at the repository root: a first run takes about a
minute of CPU, a rerun with few changed modules a few seconds. It starts in the background when the
test is collected (tests/_mypy_background.py); the test reads its answer.
"""

from __future__ import annotations

import ast
import re
import tomllib
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests import _mypy_background

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("analysis", "planning")

# Public functions allowed an ``Any`` in their signature, "module:qualname" -> why.
ANY_EXCEPTIONS: dict[str, str] = {
    "analysis.runs.layout:meta_json": "a JSON object as stored in a run file: any JSON values",
}


def _config() -> dict[str, object]:
    with open(ROOT / "pyproject.toml", "rb") as f:
        mypy = tomllib.load(f)["tool"]["mypy"]
    assert isinstance(mypy, dict)
    return mypy


def _ignored_patterns() -> list[str]:
    """Module patterns mypy still ignores (owned by a concurrent refactor, typed next)."""
    out: list[str] = []
    overrides = _config().get("overrides", [])
    assert isinstance(overrides, list)
    for override in overrides:
        if override.get("ignore_errors"):
            mods = override["module"]
            out += [mods] if isinstance(mods, str) else mods
    return out


# rig/ file -> the mypy errors it may still have (mostly handlers indexing JSON-valued results,
# the console's ring meta, the importer's scalar calibration): typed next, each entry only
# shrinks and goes (a file not listed may have none).
RIG_MYPY_CEILING: dict[str, int] = {
    "rig/cli/catalog.py": 1,
    "rig/cli/plan_check.py": 2,
    "rig/cli/plan_feed.py": 4,
    "rig/console/live.py": 7,
    "rig/console/ring.py": 3,
    "rig/log/importer.py": 4,
    "rig/log/record.py": 1,
}

_ERROR = re.compile(r"^(?P<file>[^:\s]+\.pyi?):\d+: error: ")


def _mypy_errors(output: str) -> dict[str, list[str]]:
    """mypy's error lines by file (notes and the summary left out)."""
    out: dict[str, list[str]] = {}
    for line in output.splitlines():
        m = _ERROR.match(line)
        if m:
            out.setdefault(m["file"].replace("\\", "/"), []).append(line)
    return out


def _over_ceiling(errors: dict[str, list[str]], ceiling: dict[str, int]) -> list[str]:
    """The error lines not allowed: any outside rig/ or in a rig file without a ceiling, all of a
    rig file's when it has more than its ceiling."""
    bad: list[str] = []
    for path, lines in sorted(errors.items()):
        if len(lines) > (ceiling.get(path, 0) if path.startswith("rig/") else 0):
            bad += lines
    return bad


@pytest.mark.timeout(900)
def test_mypy_strict_on_analysis_and_planning_and_rig_within_ceilings(
    pytestconfig: pytest.Config,
) -> None:
    code, output = _mypy_background.result(pytestconfig, deadline_s=840)
    errors = _mypy_errors(output)
    if code not in (0, 1) or (code == 1 and not errors):
        pytest.fail(f"mypy did not run (exit {code}):\n{output}")
    bad = _over_ceiling(errors, RIG_MYPY_CEILING)
    assert not bad, "new mypy errors (fix them; RIG_MYPY_CEILING only shrinks):\n" + "\n".join(bad)
    lower = {p: len(errors.get(p, [])) for p, n in RIG_MYPY_CEILING.items()
             if len(errors.get(p, [])) < n}  # fmt: skip
    assert not lower, f"RIG_MYPY_CEILING above the errors left: lower it to {lower}"


def test_the_ceiling_check_sees_new_errors() -> None:
    out = (
        "rig/a.py:3: error: Incompatible types  [assignment]\n"
        "rig/a.py:3: note: a note\n"
        "rig/b.py:9: error: Name x is not defined  [name-defined]\n"
        "rig/b.py:10: error: Name y is not defined  [name-defined]\n"
        "planning/c.py:1: error: Missing return  [return]\n"
        "Found 4 errors in 3 files\n"
    )
    errors = _mypy_errors(out)
    assert {p: len(v) for p, v in errors.items()} == {"rig/a.py": 1, "rig/b.py": 2,
                                                      "planning/c.py": 1}  # fmt: skip
    bad = _over_ceiling(errors, {"rig/a.py": 1, "rig/b.py": 1, "planning/c.py": 5})
    assert [ln.split(":")[0] for ln in bad] == ["planning/c.py", "rig/b.py", "rig/b.py"]
    assert _over_ceiling(errors, {"rig/a.py": 1, "rig/b.py": 2}) == [bad[0]]


def _matches(module: str, pattern: str) -> bool:
    """mypy's module patterns: ``a.b.*`` is ``a.b`` and everything under it."""
    if pattern.endswith(".*"):
        return module == pattern[:-2] or module.startswith(pattern[:-1])
    return module == pattern


def _modules() -> Iterator[tuple[str, Path]]:
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            yield ".".join(parts), path


def _public(module: str) -> bool:
    return not any(p.startswith("_") for p in module.split("."))


def _any_in(node: ast.expr | None) -> bool:
    """Whether an annotation names ``Any`` (``Any``, ``typing.Any``, or inside a string)."""
    if node is None:
        return False
    for sub in ast.walk(node):
        if isinstance(sub, ast.Name) and sub.id == "Any":
            return True
        if isinstance(sub, ast.Attribute) and sub.attr == "Any":
            return True
        if isinstance(sub, ast.Constant) and isinstance(sub.value, str):
            try:
                inner = ast.parse(sub.value, mode="eval").body
            except SyntaxError:
                continue
            if _any_in(inner):
                return True
    return False


def _signature_has_any(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    a = fn.args
    params = [*a.posonlyargs, *a.args, *a.kwonlyargs, a.vararg, a.kwarg]
    return _any_in(fn.returns) or any(p is not None and _any_in(p.annotation) for p in params)


def _public_functions(
    tree: ast.Module,
) -> Iterator[tuple[str, ast.FunctionDef | ast.AsyncFunctionDef]]:
    """Module-level functions and methods of module-level classes, public by name (a class's
    ``__init__`` is part of its public face)."""
    funcs = (ast.FunctionDef, ast.AsyncFunctionDef)
    for node in tree.body:
        if isinstance(node, funcs) and not node.name.startswith("_"):
            yield node.name, node
        elif isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
            for item in node.body:
                if isinstance(item, funcs) and (
                    not item.name.startswith("_") or item.name == "__init__"
                ):
                    yield f"{node.name}.{item.name}", item


def test_no_any_in_public_signatures() -> None:
    ignored = _ignored_patterns()
    found: list[str] = []
    for module, path in _modules():
        if not _public(module) or any(_matches(module, p) for p in ignored):
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        for qualname, fn in _public_functions(tree):
            if _signature_has_any(fn):
                found.append(f"{module}:{qualname}")
    rel = {k for k in found if k not in ANY_EXCEPTIONS}
    assert not rel, "Any in a public signature (type it, or add to ANY_EXCEPTIONS with why):\n" + (
        "\n".join(sorted(rel))
    )
    stale = sorted(set(ANY_EXCEPTIONS) - set(found))
    assert not stale, f"ANY_EXCEPTIONS entries no longer needed: {stale}"


def test_any_check_sees_any() -> None:
    """The AST check itself: every spelling of Any in a signature is seen, others are not."""
    src = (
        "def a(x: Any) -> int: ...\n"
        "def b(x: int) -> dict[str, typing.Any]: ...\n"
        "def c(*args: 'list[Any]') -> None: ...\n"
        "def d(**kw: object) -> 'Sequence[int]': ...\n"
    )
    fns = dict(_public_functions(ast.parse(src)))
    assert {k: _signature_has_any(f) for k, f in fns.items()} == {
        "a": True,
        "b": True,
        "c": True,
        "d": False,
    }


# -- job results: no bare dict across a package face, no Any in rig's public signatures ----------
# Issue 30 item 4. A public function (module-level, or a method of a public class, in a public
# module) of analysis/, planning/ and rig/ returns a typed contract: a TypedDict where the result
# is JSON-shaped (the CLI prints it), a frozen dataclass where code reads it. Neither a
# ``-> dict`` / ``-> dict[...]`` return (also in a union) nor ``Any`` anywhere in the signature
# (analysis/ and planning/: test_no_any_in_public_signatures above, with mypy).
# Out of scope: rig.cli (parsing and printing; moved out by issue 30 item 5) and the packages
# another branch types now (analysis.forces, analysis.identify, planning.nc, planning.orient:
# mypy strict and the Any check above take them once their overrides go).
RESULT_PACKAGES = ("analysis", "planning", "rig")
RESULT_SKIP = (
    "rig.cli",
    "analysis.forces",
    "analysis.identify",
    "planning.nc",
    "planning.orient",
)

# "module:qualname" -> why a dict return is the contract: a homogeneous map keyed by data (names,
# block numbers), its values typed; a map whose keys are a fixed schema is a TypedDict instead.
DICT_RETURNS: dict[str, str] = {
    "analysis.runs.layout:meta_json": "a JSON object as a run file stores it (conditions, "
    "status, acquisition: free-form, read by key)",
    "analysis.config:load_tools": "tool name -> EndMill | FaceMill (the catalogue's names)",
    "analysis.config:load_materials": "material name -> Material (the catalogue's names)",
    "planning.feed.job:resolve_rules": "one FeedRule, or tool (T1, T2, ...) -> FeedRule",
    "planning.limits.check:Pieces.quantities": "limit name -> its value per piece (NDArray), "
    "iterated by limit (force, power, torque, chip, stability, deflection, ...)",
    "planning.limits.check:Pieces.allowed": "limit name -> its allowed value, for the limits "
    "that are on (iterated with quantities)",
    "planning.limits.check:CheckResult.block_caps": "block number -> its highest feed, mm/min",
    "planning.rough.planner:RoughPlanner.plan_all": "method name -> RoughPlan",
    "planning.stock.plans:parse_tool_spec": "one tool, or tool (T1, T2, ...) -> its spec",
    "rig.campaign.manifest:experiment_fields": "the campaign file's field paths "
    "(matrix[0].depth_mm, ...) -> their JSON values: the keys are the user's file",
    "rig.campaign.manifest:campaign_inputs": "input name (config, tool, material, machine, rig) "
    "-> InputRecord, iterated by name against the manifest's",
    "rig.campaign.runner:tap_records": "direction (x, y) -> the tap record's path",
    "rig.dnc.execution:ExecTracker.pop_started": "line index -> its execution start, s",
    "rig.dnc.execution:TimedTracker.pop_started": "line index -> its execution start, s",
    "rig.report.base:LoadedRun.conditions": "the run file's recorded conditions: free-form keys "
    "(the campaign's, an import's, a recorder's --condition pairs)",
    "rig.report.demo:DemoResult.facemill": "the face-mill report section's summary: typed with "
    "the report sections' summaries (Section.summary), next",
    "rig.sim.controllers:parse_knobs": "knob name -> KnobValue: the user's KNOB=VALUE pairs, "
    "checked against the controller's keywords",
}

# "module:qualname" -> why rig's signature keeps an Any (analysis/ and planning/: ANY_EXCEPTIONS).
RIG_ANY: dict[str, str] = {
    # ** keywords forwarded unchanged to a base class or a library, which types them
    "rig.dnc.fanuc:FanucStreamer.__init__": "**stream_kw forwarded to StreamerBase.__init__",
    "rig.dnc.grbl:GrblStreamer.__init__": "**stream_kw forwarded to StreamerBase.__init__",
    "rig.sim.fanuc:SimFanuc.__init__": "**base_kw forwarded to SimControllerBase.__init__",
    "rig.sim.grbl:SimGrbl.__init__": "**base_kw forwarded to SimControllerBase.__init__",
    "rig.terminal:Progress.__init__": "**tqdm_kw forwarded to tqdm (no type information)",
    # third-party objects without type information
    "rig.daq.ni:NiDaq.__init__": "nidaqmx's Task and readers: nidaqmx ships no types",
    "rig.dnc.guard:HoldGuard.start_for": "a pyserial port (or a URL port without a file "
    "descriptor): pyserial ships no types",
    "rig.console.server:make_app": "its Guard with the Starlette app's state set on it as an "
    "attribute (dynamic): Guard declaring state is the console branch's",
    # the independent face-mill simulator shares no model code with analysis.forces (on purpose)
    "rig.sim.facemill_independent:insert_forces": "duck-typed tool: no analysis.forces import",
    "rig.sim.facemill_independent:simulate": "duck-typed tool and coefficients (as above)",
    # a type that lives above the package: a Protocol in the lower package is the next step
    "rig.adaptive.session:AdaptiveSession.__init__": "wraps rig.campaign's RigSession (above "
    "rig.adaptive) and sets its adaptive_controller",
    "rig.adaptive.session:AdaptiveSession.start": "the program and rig.log's RunWriter, as "
    "RigSession.start takes them (above rig.adaptive)",
    "rig.dnc.sinks:LoggerSink.__init__": "rig.log's RunWriter (above rig.dnc)",
    "rig.dnc.grbl_halt:GrblControl.__init__": "its GrblStreamer, which imports this module (an "
    "import even for typing is a cycle to test_layers): a Protocol of its fields, next",
    "rig.dnc.grbl_lost:LostAnswers.__init__": "its GrblStreamer (as GrblControl)",
    "rig.dnc.grbl_receive:GrblReceiver.__init__": "its GrblStreamer (as GrblControl)",
    "rig.dnc.grbl_check:prepare_lines": "GRBL's parse of each line: planning.nc.grbl's, typed "
    "by the concurrent planning.nc branch",
    # JSON from outside the process (the browser, the ring's meta/status/commands), free-form;
    # rig.console's bodies are edited by the console branch now: typed once it lands
    "rig.console.forces:force_n": "the ring's run meta (JSON)",
    "rig.console.guard:Guard.__init__": "the inner ASGI app (Starlette's or a test's)",
    "rig.console.guard:Guard.check": "the ASGI scope (a framework dict)",
    "rig.console.guard:parse_message": "a page's websocket message (JSON)",
    "rig.console.hub:Hub.runs": "the runs' rows for the page from the manifest (JSON)",
    "rig.console.ring:RingWriter.begin_run": "the run meta (JSON)",
    "rig.console.ring:RingWriter.put_meta": "the run meta (JSON)",
    "rig.console.ring:RingWriter.put_status": "the status (JSON)",
    "rig.console.ring:RingWriter.read_command": "a page's command (JSON)",
    "rig.console.ring:RingReader.send_command": "a page's command (JSON)",
    # report rows: typed with the report sections' summaries, next
    "rig.report.adaptive:adaptive_entries": "the adaptive report's entries (the adaptive "
    "branch adds fields now) and LoadedRun rows",
    "rig.report.base:LoadedRun.conditions": "the run's recorded conditions (DICT_RETURNS)",
    "rig.report.demo:DemoResult.facemill": "the face-mill section's summary (DICT_RETURNS)",
}


def _dict_in(node: ast.expr | None) -> bool:
    """Whether a return annotation is ``dict`` or ``dict[...]``, alone or in a union (also as a
    string)."""
    if node is None:
        return False
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        try:
            node = ast.parse(node.value, mode="eval").body
        except SyntaxError:
            return False
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.BitOr):
        return _dict_in(node.left) or _dict_in(node.right)
    if isinstance(node, ast.Subscript):
        node = node.value
    return (isinstance(node, ast.Name) and node.id in ("dict", "Dict")) or (
        isinstance(node, ast.Attribute) and node.attr in ("dict", "Dict")
    )


def _result_modules() -> Iterator[tuple[str, ast.Module]]:
    for pkg in RESULT_PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            module = ".".join(parts)
            if not _public(module) or any(_matches(module, f"{s}.*") for s in RESULT_SKIP):
                continue
            yield module, ast.parse(path.read_text(encoding="utf-8"), str(path))


def _untyped_results() -> tuple[list[str], list[str]]:
    """(public functions returning a dict, rig's public functions with an Any)."""
    dicts: list[str] = []
    anys: list[str] = []
    for module, tree in _result_modules():
        for qualname, fn in _public_functions(tree):
            if _dict_in(fn.returns):
                dicts.append(f"{module}:{qualname}")
            if module.startswith("rig") and _signature_has_any(fn):
                anys.append(f"{module}:{qualname}")
    return dicts, anys


def test_no_bare_dict_or_any_across_package_faces() -> None:
    dicts, anys = _untyped_results()
    for found, allowed, what in (
        (dicts, DICT_RETURNS, "a dict return (a TypedDict or a frozen dataclass, or DICT_RETURNS "
                              "with why)"),
        (anys, RIG_ANY, "Any in a public signature of rig (type it, or RIG_ANY with why)"),
    ):  # fmt: skip
        new = sorted(set(found) - set(allowed))
        assert not new, f"{what}:\n" + "\n".join(new)
        stale = sorted(set(allowed) - set(found))
        assert not stale, f"allow-list entries no longer needed: {stale}"


def test_the_dict_check_sees_dict_returns() -> None:
    src = (
        "def a() -> dict: ...\n"
        "def b() -> dict[str, int] | None: ...\n"
        "def c() -> 'dict[str, object]': ...\n"
        "def d() -> Mapping[str, int]: ...\n"
        "def e() -> RunSummary: ...\n"
        "class K:\n"
        "    def f(self) -> typing.Dict[str, int]: ...\n"
        "    def _g(self) -> dict: ...\n"
    )
    fns = dict(_public_functions(ast.parse(src)))
    assert {k: _dict_in(f.returns) for k, f in fns.items()} == {
        "a": True,
        "b": True,
        "c": True,
        "d": False,
        "e": False,
        "K.f": True,
    }

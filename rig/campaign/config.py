"""The campaign TOML: its validated model (the tables: :mod:`rig.campaign.schema`), the expansion
of its test matrix, and the checks that every test is possible on the named machine with the
named tool before anything runs.

A campaign file has these tables (all lengths mm, feeds mm/min or mm/tooth, speeds rpm)::

    [campaign]      name, machine, tool, material, rig = "sim" | "real", output_dir, ...
    [program]       kind = "facemill-pass" | "slot" | "feed-sweep" | "step-depth" and its geometry
    [daq]           optional overrides of configs/rig.toml's DAQ (rate_hz, ...)
    [sim]           the simulated rig: speed, noise, drift, hum, seed and sim_ fault knobs
    [tap_test]      optional: an impulse-hammer test of the tool before the cuts (its modes)
    [suspenders]    conditions that pause or stop a run on their own
    [chatter]       optional: how chatter is judged (report and the on_chatter suspender)
    [analysis]      what runs after the campaign (kind and which groups feed it)
    [adaptive]      optional: GRBL overrides from the live force for some groups (rig.adaptive)
    [[matrix]]      one or more groups; every list-valued field is expanded as a product
    [[tests]]       single tests (scalars only), appended after the matrix

See ``configs/campaigns/*.toml`` for commented examples.
"""

from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from analysis.config import (
    EndMill,
    FaceMill,
    MachineConfig,
    Material,
    RigConfig,
    catalog_source,
    config_dir,
    get_material,
    get_tool,
    load_machine,
    load_rig,
    user_catalogs,
)
from analysis.errors import ConfigError
from analysis.forces import ENDMILL, FACEMILL, ForceModel, model_for
from analysis.validation import read_toml, validate
from rig.campaign.results import RunConditionsJson
from rig.campaign.schema import (  # noqa: F401 - the tables, importable from here as before
    AdaptiveSection,
    AnalysisSection,
    CampaignFile,
    CampaignSection,
    ChatterSection,
    DaqOverride,
    FeedRuleSection,
    MatrixEntry,
    ProgramSection,
    SimSection,
    SuspenderSection,
    TapTestSection,
)


@dataclass(frozen=True)
class RunConditions:
    """One test of a campaign, after expansion. Feeds in both units are filled in."""

    index: int
    name: str
    group: str
    fz_mm: float
    feed_mm_min: float
    depth_mm: float
    width_mm: float
    spindle_rpm: float
    feed_mode: str
    rule: str | None
    source_line: int | None

    def as_dict(self) -> RunConditionsJson:
        """Every field but ``source_line``, in order."""
        return {"index": self.index, "name": self.name, "group": self.group, "fz_mm": self.fz_mm,
                "feed_mm_min": self.feed_mm_min, "depth_mm": self.depth_mm,
                "width_mm": self.width_mm, "spindle_rpm": self.spindle_rpm,
                "feed_mode": self.feed_mode, "rule": self.rule}  # fmt: skip


@dataclass(frozen=True)
class Campaign:
    """A loaded, validated campaign with its resolved configs and expanded tests."""

    path: Path
    text: str
    spec: CampaignFile
    machine: MachineConfig
    tool: EndMill | FaceMill
    material: Material
    rig: RigConfig
    tests: tuple[RunConditions, ...]
    # the catalogue file each of the tool and the material was read from ("tools"/"materials":
    # the campaign's own, a --tools/--materials one or the shipped one), for messages
    sources: tuple[tuple[str, str], ...] = ()

    @property
    def name(self) -> str:
        return self.spec.campaign.name

    def source(self, kind: str) -> str:
        """The file the tool ("tools") or the material ("materials") came from, or ""."""
        return dict(self.sources).get(kind, "")

    @property
    def teeth(self) -> int:
        return _teeth(self.tool)


def _teeth(tool: EndMill | FaceMill) -> int:
    return model_for(tool).teeth(tool)  # inserts of a face mill, flutes of an end mill


def _as_list(v: Any) -> list[Any]:
    return list(v) if isinstance(v, list) else [v]


def _table_lines(text: str, table: str) -> list[int]:
    """1-based lines of each ``[[table]]`` header, in order."""
    pat = re.compile(r"^\s*\[\[\s*" + re.escape(table) + r"\s*\]\]")
    return [i + 1 for i, line in enumerate(text.splitlines()) if pat.match(line)]


def _fmt(x: float) -> str:
    return f"{x:g}"


#: The most runs a campaign may hold: a lab cuts tens to hundreds; a matrix beyond this is a
#: slip (two 2000-value lists made 4 million runs, and a --dry-run that did not end in 60 s)
MAX_CAMPAIGN_RUNS = 10_000


def _matrix_size_problem(spec: CampaignFile, where: str, lines: list[int]) -> str:
    """A line when the matrix makes more than :data:`MAX_CAMPAIGN_RUNS` runs ("" if not),
    counted from the list lengths, before anything is expanded."""
    total, sizes = 0, []
    for k, e in enumerate(spec.matrix + spec.tests):
        factors = {name: len(_as_list(getattr(e, name))) for name in
                   ("spindle_rpm", "fz_mm", "feed_mm_min", "depth_mm", "width_mm", "feed_mode")
                   if getattr(e, name) is not None}  # fmt: skip
        factors["repeat"] = e.repeat
        n = math.prod(factors.values())
        total += n
        sizes.append((n, k, factors))
    if total <= MAX_CAMPAIGN_RUNS:
        return ""
    n, k, factors = max(sizes)
    table = f"matrix[{k}]" if k < len(spec.matrix) else f"tests[{k - len(spec.matrix)}]"
    line = lines[k] if k < len(lines) else 0
    product = " x ".join(f"{v} {name}" for name, v in factors.items() if v > 1)
    place = f"{where}:{line}" if line else where
    return (f"{place}: {table} makes {n} runs ({product}), the campaign {total}; at most "
            f"{MAX_CAMPAIGN_RUNS} runs in a campaign (split it)")  # fmt: skip


def expand_matrix(
    entries: tuple[MatrixEntry, ...],
    tool: EndMill | FaceMill,
    lines: list[int] | None = None,
    block_width_mm: float | None = None,
) -> list[RunConditions]:
    """Expand matrix groups into tests (product of list-valued fields, in file order).

    Width defaults to the tool diameter for end mills (a slot) and to the block width for face
    mills (the cutter spans the block); depth must be given.
    """
    out: list[RunConditions] = []
    teeth = _teeth(tool)
    for k, e in enumerate(entries):
        line = lines[k] if lines and k < len(lines) else None
        feeds = _as_list(e.fz_mm if e.fz_mm is not None else e.feed_mm_min)
        width_default = tool.diameter_mm if ENDMILL.describes(tool) else block_width_mm
        widths = _as_list(e.width_mm if e.width_mm is not None else width_default)
        depths = _as_list(e.depth_mm)
        for rpm, feed, depth, width, mode, rep in itertools.product(
            _as_list(e.spindle_rpm), feeds, depths, widths, _as_list(e.feed_mode), range(e.repeat)
        ):
            if e.fz_mm is not None:
                fz = float(feed)
                f_min = fz * teeth * rpm
            else:
                f_min = float(feed)
                fz = f_min / (teeth * rpm)
            name = f"{e.group}-n{len(out):03d}-fz{fz:.4g}-d{_fmt(depth or 0)}-s{_fmt(rpm)}"
            if mode != "constant":
                name += f"-{mode}"
            if e.repeat > 1:
                name += f"-r{rep}"
            out.append(
                RunConditions(
                    index=len(out),
                    name=name,
                    group=e.group,
                    fz_mm=fz,
                    feed_mm_min=f_min,
                    depth_mm=float(depth) if depth is not None else float("nan"),
                    width_mm=float(width) if width is not None else float("nan"),
                    spindle_rpm=float(rpm),
                    feed_mode=mode,
                    rule=e.rule,
                    source_line=line,
                )
            )
    return out


def check_tests(
    tests: list[RunConditions],
    machine: MachineConfig,
    tool: EndMill | FaceMill,
    program: ProgramSection,
    where: str,
    text: str = "",
) -> None:
    """Raise :class:`ConfigError` listing every impossible condition (all, not just the first),
    once per field, with the line of the field in ``text`` and the tests it affects."""
    found: dict[tuple[str, str], list[RunConditions]] = {}
    program_line = _table_line(text, "program")

    def add(t: RunConditions, fields: tuple[str, ...], msg: str, in_program: bool = False) -> None:
        start = program_line if in_program else t.source_line
        line = next((n for f in fields if (n := _field_line(text, start, f))), start)
        place = f"{where}:{line}" if line else where
        found.setdefault((place, msg), []).append(t)

    depth_limit = tool.depth_limit_mm if FACEMILL.describes(tool) else tool.flute_length_mm
    sweep = program.kind == "feed-sweep"
    for t in tests:
        for f in list(program.sweep_feeds_mm_min) if sweep else [t.feed_mm_min]:
            fields = ("sweep_feeds_mm_min",) if sweep else ("fz_mm", "feed_mm_min")
            how = (
                ""
                if sweep
                else f" (fz {t.fz_mm:g} mm/tooth x {_teeth(tool)} x {t.spindle_rpm:g} rpm)"
            )
            if f > machine.feed_max_mm_min:
                add(t, fields, f"feed = {f:g} mm/min{how} is above machine '{machine.name}' "
                    f"feed_max_mm_min = {machine.feed_max_mm_min:g} mm/min", sweep)  # fmt: skip
            if f < machine.feed_min_mm_min:
                add(t, fields, f"feed = {f:g} mm/min is below feed_min_mm_min = "
                    f"{machine.feed_min_mm_min:g} mm/min", sweep)  # fmt: skip
        if t.spindle_rpm > machine.spindle_max_rpm:
            add(t, ("spindle_rpm",), f"spindle_rpm = {t.spindle_rpm:g} is above machine "
                f"'{machine.name}' spindle_max_rpm = {machine.spindle_max_rpm:g} rpm")  # fmt: skip
        steps = program.kind == "step-depth"
        for d in list(program.step_depths_mm) if steps else [t.depth_mm]:
            fields = ("step_depths_mm",) if steps else ("depth_mm",)
            if not d == d:  # NaN
                add(t, fields, "depth_mm missing: give the axial depth of cut (mm)", steps)
            elif d > depth_limit:
                kind = "usable insert edge" if FACEMILL.describes(tool) else "flute length"
                add(t, fields, f"depth_mm = {d:g} is beyond the {kind} of tool "
                    f"'{program_tool(tool)}' ({depth_limit:.3g} mm)", steps)  # fmt: skip
        if ENDMILL.describes(tool) and t.width_mm > tool.diameter_mm + 1e-9:
            add(t, ("width_mm",), f"width_mm = {t.width_mm:g} exceeds the tool diameter "
                f"{tool.diameter_mm:g} mm (one pass cuts at most a slot)")  # fmt: skip
        if t.width_mm == t.width_mm and t.width_mm > program.block_width_mm + 1e-9:
            add(t, ("width_mm",), f"width_mm = {t.width_mm:g} exceeds program.block_width_mm = "
                f"{program.block_width_mm:g} mm")  # fmt: skip
        if t.feed_mode == "post-processed" and not t.rule:
            add(t, ("feed_mode",), "feed_mode = 'post-processed' needs rule = 'FILE' (a rule)")
    problems = [f"{place}: {_which(ts)}: {msg}" for (place, msg), ts in found.items()]
    if FACEMILL.describes(tool) and program.kind != "facemill-pass":
        problems.append(
            f"{where}: program.kind = '{program.kind}' needs an end mill, got a face mill"
        )
    if ENDMILL.describes(tool) and program.kind == "facemill-pass":
        problems.append(f"{where}: program.kind = 'facemill-pass' needs a face mill tool")
    if problems:
        raise ConfigError("\n".join(problems))


def _which(tests: list[RunConditions]) -> str:
    """'test 3 (group)' or 'tests 0-9 (group)' / 'tests 1, 4 (a, b)'."""
    idx = [t.index for t in tests]
    groups = ", ".join(dict.fromkeys(t.group for t in tests))
    if len(idx) == 1:
        return f"test {idx[0]} ({groups})"
    run = idx == list(range(idx[0], idx[0] + len(idx)))
    return (
        f"tests {idx[0]}-{idx[-1]} ({groups})"
        if run
        else f"tests {', '.join(map(str, idx))} ({groups})"
    )


def _table_line(text: str, table: str) -> int:
    """1-based line of the ``[table]`` header (0 if absent)."""
    pat = re.compile(r"^\s*\[\s*" + re.escape(table) + r"\s*\]")
    return next((i + 1 for i, ln in enumerate(text.splitlines()) if pat.match(ln)), 0)


def _field_line(text: str, table_line: int | None, field: str) -> int:
    """1-based line of ``field = ...`` in the table whose header is at ``table_line`` (0: none)."""
    if not text or not table_line:
        return 0
    pat = re.compile(r"^\s*" + re.escape(field) + r"\s*=")
    lines = text.splitlines()
    for i in range(table_line, len(lines)):
        if lines[i].lstrip().startswith("["):
            break
        if pat.match(lines[i]):
            return i + 1
    return 0


def program_tool(tool: EndMill | FaceMill) -> str:
    return tool.description or tool.kind


def _resolve_campaign(path: str | Path) -> Path:
    p = Path(path)
    if p.exists() or p.suffix == ".toml":
        return p
    cand = config_dir() / "campaigns" / f"{path}.toml"
    if cand.exists():
        return cand
    known = sorted(q.stem for q in (config_dir() / "campaigns").glob("*.toml"))
    raise ConfigError(f"campaign '{path}' not found: not a file, and not one of {known}")


def load_campaign(path: str | Path) -> Campaign:
    """Load and check a campaign: every error (config, tool, material, impossible test) is a
    :class:`ConfigError` raised here, before anything runs."""
    p = _resolve_campaign(path)
    data, text = read_toml(p)
    spec = validate(CampaignFile, data, str(p), text)
    c = spec.campaign
    problems: list[str] = []
    sources: tuple[tuple[str, str], ...] = ()
    camp_line = _table_line(text, "campaign")

    def where(table_line: int, field: str) -> str:
        line = _field_line(text, table_line, field) or table_line
        return f"{p}:{line}" if line else str(p)

    def load(what: str, fn: Any, name: Any) -> Any:
        try:
            return fn(name)
        except ConfigError as exc:
            problems.append(f"{where(camp_line, what)}: campaign.{what} = {name!r}: {exc}")
            return None

    machine = load("machine", load_machine, c.machine)
    tool = material = None
    files = [None if f is None else p.parent / f for f in (c.tools_file, c.materials_file)]
    try:
        with user_catalogs(*files):
            tool = load("tool", get_tool, c.tool)
            material = load("material", get_material, c.material)
            sources = tuple((k, catalog_source(k, n)) for k, n in
                            (("tools", c.tool), ("materials", c.material)))  # fmt: skip
    except ConfigError as exc:  # a bad catalogue file: its own message names it
        problems.append(str(exc))
    rig = load("rig_config", load_rig, c.rig_config)
    if c.rig == "sim" and tool is not None and material is not None:
        need = "facemill" if FACEMILL.describes(tool) else "endmill"
        if getattr(material, need) is None:
            problems.append(
                f"{where(camp_line, 'material')}: campaign.material = {c.material!r} has no "
                f"[{need}] coefficients; the simulated rig needs them as its truth for tool "
                f"{c.tool!r}"
            )
    if rig is not None:
        problems += _rate_problems(spec, rig, where(_table_line(text, "daq"), "rate_hz"))
    problems += _analysis_problems(spec, tool, where(_table_line(text, "analysis"), "kind"))
    tests: list[RunConditions] = []
    lines = _table_lines(text, "matrix") + _table_lines(text, "tests")
    too_big = _matrix_size_problem(spec, str(p), lines)
    if too_big:  # nothing expanded: refused at once, --dry-run too
        problems.append(too_big)
    elif tool is not None:
        tests = expand_matrix(spec.matrix + spec.tests, tool, lines, spec.program.block_width_mm)
        if machine is not None:
            try:
                check_tests(tests, machine, tool, spec.program, str(p), text)
            except ConfigError as exc:
                problems += str(exc).splitlines()
    if problems:
        raise ConfigError("\n".join(problems))
    assert tool is not None and material is not None  # else load() added a problem
    return Campaign(p, text, spec, machine, tool, material, rig, tuple(tests), sources)


def _rate_problems(spec: CampaignFile, rig: RigConfig, where: str) -> list[str]:
    """The DAQ rate against what the recording needs: above twice the dynamometer's highest mode
    (below, the mode aliases into the force band), and a rest window of samples."""
    rate = spec.daq.rate_hz or rig.daq.rate_hz
    name = "daq.rate_hz" if spec.daq.rate_hz else "rig [daq] rate_hz"
    out = []
    if rig.dynamometer.modes:
        top = max(rig.dynamometer.modes, key=lambda m: m.frequency_hz)
        if rate < 2 * top.frequency_hz:
            out.append(
                f"{where}: {name} = {rate:g}: below twice the highest mode of the "
                f"{rig.dynamometer.model} ({top.axis} {top.frequency_hz:g} Hz): expected >= "
                f"{2 * top.frequency_hz:g} Hz"
            )
    if rate * spec.daq.rest_s < 100:
        out.append(f"{where}: {name} = {rate:g} with daq.rest_s = {spec.daq.rest_s:g}: fewer than "
                   "100 samples at rest for the zero; expected rate x rest >= 100")  # fmt: skip
    return out


_ANALYSIS_TOOL: dict[str, ForceModel] = {
    "facemill-coefficients": FACEMILL,
    "feed-rule": ENDMILL,
    "afc-compare": ENDMILL,
    "stability-sweep": ENDMILL,
}


def _analysis_problems(
    spec: CampaignFile, tool: EndMill | FaceMill | None, where: str
) -> list[str]:
    """[analysis] against the rest: its groups exist, its tool kind, its feed rule."""
    a = spec.analysis
    groups = {e.group for e in spec.matrix + spec.tests}
    out = []
    for field in ("identify_groups", "validate_groups", "compare_groups"):
        unknown = [g for g in getattr(a, field) if g not in groups]
        if unknown:
            out.append(f"{where}: analysis.{field} = {list(getattr(a, field))}: no group "
                       f"{unknown[0]!r}; expected one of {sorted(groups)}")  # fmt: skip
    need = _ANALYSIS_TOOL.get(a.kind)
    if need is not None and tool is not None and not need.describes(tool):
        kind = "a face mill" if need is FACEMILL else "an end mill"
        out.append(f"{where}: analysis.kind = {a.kind!r} needs {kind}, tool "
                   f"{spec.campaign.tool!r} is not one")  # fmt: skip
    if a.kind == "afc-compare" and len(a.compare_groups) != 2:
        out.append(f"{where}: analysis.compare_groups = {list(a.compare_groups)}: expected two "
                   "groups (constant, adjusted)")  # fmt: skip
    if a.kind == "stability-sweep" and spec.tap_test is None:
        out.append(f"{where}: analysis.kind = 'stability-sweep' needs a [tap_test] table (the "
                   "tool's modes come from it)")  # fmt: skip
    tap = spec.tap_test
    if tap is not None and spec.campaign.rig == "real" and set(tap.files) != {"x", "y"}:
        out.append(f"{where}: [tap_test] on a real rig needs files = {{ x = 'FILE', y = 'FILE' "
                   f"}} (hammer records, `analyze modal`), got {sorted(tap.files)}")  # fmt: skip
    if a.kind == "feed-rule" and spec.feed_rule is None:
        out.append(f"{where}: analysis.kind = 'feed-rule' needs a [feed_rule] table (min, base, "
                   "max feed in mm/min, reference_depth_mm)")  # fmt: skip
    return out

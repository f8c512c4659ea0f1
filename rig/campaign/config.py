"""The campaign TOML: its validated model, the expansion of its test matrix, and the checks that
every test is possible on the named machine with the named tool before anything runs.

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
from typing import Any, Literal

from pydantic import Field, model_validator

from analysis.config import (
    EndMill,
    FaceMill,
    MachineConfig,
    Material,
    RigConfig,
    ToolMode,
    catalog_source,
    config_dir,
    get_material,
    get_tool,
    load_machine,
    load_rig,
    user_catalogs,
)
from analysis.errors import ConfigError
from analysis.validation import Model, read_toml, validate

FloatOrList = float | list[float]

ProgramKind = Literal["facemill-pass", "slot", "feed-sweep", "step-depth"]
FeedMode = Literal["constant", "post-processed"]


class CampaignSection(Model):
    name: str = Field(min_length=1, pattern=r"^[A-Za-z0-9_.-]+$")
    description: str = ""
    machine: str = Field(min_length=1, description="machine name in configs/machines or a path")
    tool: str = Field(min_length=1, description="tool name in configs/tools.toml")
    material: str = Field(min_length=1, description="material name in configs/materials.toml")
    rig: Literal["sim", "real"] = Field("sim", description="sim or real")
    rig_config: str | None = Field(None, description="rig TOML (default configs/rig.toml)")
    output_dir: str = Field("data/campaigns", description="folder of campaign folders")
    operator: str = ""
    tools_file: str | None = Field(
        None, description="your tool catalogue, relative to the campaign file; its names shadow "
        "configs/tools.toml"
    )  # fmt: skip
    materials_file: str | None = Field(
        None, description="your material catalogue, relative to the campaign file; its names "
        "shadow configs/materials.toml"
    )  # fmt: skip


class ProgramSection(Model):
    """Geometry of the generated test programs. The block's top face is Z = 0 (work offset G54),
    it spans X 0..block_length_mm and Y -block_width_mm/2..+block_width_mm/2."""

    kind: ProgramKind = Field(description="generator")
    block_length_mm: float = Field(30.0, gt=0, le=2000, description="mm, along the cut (X)")
    block_width_mm: float = Field(50.0, gt=0, le=2000, description="mm, across the cut (Y)")
    approach_mm: float = Field(3.0, ge=0, le=100, description="mm, air cut before the block")
    safe_z_mm: float = Field(5.0, gt=0, le=200, description="mm above the block top")
    offset_y_mm: float = Field(0.0, ge=-1000, le=1000, description="mm, cutter path off centre")
    step_depths_mm: tuple[float, ...] = Field(
        (), description="mm, step-depth cut: depth of cut on each step, in cutting order"
    )
    sweep_feeds_mm_min: tuple[float, ...] = Field(
        (), description="mm/min, feed-sweep: the feeds stepped along one slot"
    )
    program_number: int = Field(1001, ge=1, le=9999, description="Fanuc O number")

    @model_validator(mode="after")
    def _kind_fields(self) -> ProgramSection:
        if self.kind == "step-depth" and len(self.step_depths_mm) < 2:
            raise ValueError("step_depths_mm needs >= 2 depths (mm) for a step-depth program")
        if any(d <= 0 for d in self.step_depths_mm):
            raise ValueError(f"step_depths_mm = {list(self.step_depths_mm)}: must be > 0 (mm)")
        if self.kind == "feed-sweep" and len(self.sweep_feeds_mm_min) < 2:
            raise ValueError("sweep_feeds_mm_min needs >= 2 feeds (mm/min) for a feed-sweep")
        if any(f <= 0 for f in self.sweep_feeds_mm_min):
            raise ValueError(f"sweep_feeds_mm_min = {list(self.sweep_feeds_mm_min)}: must be > 0")
        return self


class DaqOverride(Model):
    rate_hz: float | None = Field(None, gt=0, le=10_000_000, description="Hz, per channel")
    rest_s: float = Field(
        1.0, gt=0, le=60, description="s at rest before and after each cut: zero and drift fit"
    )
    read_interval_s: float | None = Field(None, gt=0, le=10, description="s between reads")


class SimSection(Model):
    """The simulated rig. Noise, drift and hum are given in newtons at the amplifier output."""

    speed: float = Field(40.0, gt=0, le=10_000, description="simulated s per wall s")
    noise_n: float = Field(1.0, ge=0, le=1e4, description="N, rms white noise per channel")
    drift_n_s: float = Field(0.05, ge=-1e3, le=1e3, description="N/s, charge amplifier drift")
    hum_n: float = Field(0.5, ge=0, le=1e4, description="N, mains hum amplitude")
    hum_hz: float = Field(50.0, gt=0, le=1000, description="Hz, mains frequency")
    seed: int = Field(2003, ge=0, description="rng seed")
    protocol: Literal["fanuc", "grbl"] | None = Field(
        None, description="simulated controller (default: the machine's dialect)"
    )
    link_timeout_s: float = Field(
        10.0, gt=0, le=600, description="s, DNC link timeout on the simulated rig (wall s)"
    )
    sim_controller_stall_after_block: int | None = Field(
        None, ge=0, description="blocks received, then the controller stops answering"
    )
    sim_alarm_at_block: int | None = Field(
        None, ge=0, description="the controller raises an alarm when this block starts"
    )
    sim_daq_overflow_at_s: float | None = Field(
        None, gt=0, description="s after the DAQ starts: its buffer overflows"
    )
    sim_interlock_at_s: float | None = Field(
        None, gt=0, description="s after streaming starts: the door interlock trips"
    )
    sim_fault_run: int = Field(0, ge=0, description="index of the run the sim_ faults hit")
    tool_modes: tuple[ToolMode, ...] | None = Field(
        None, description="the tool's modes for the regenerative twin (default: the tool's)"
    )
    tool_max_chip_mm: float | None = Field(
        None, gt=0, le=2, description="mm, the fitted edge's max_chip_mm (default: the tool's)"
    )
    force_model: Literal["seed003", "independent"] = Field(
        "seed003", description="face mills' forces: analysis.forces (seed003) or the simulator "
        "written apart from it (independent: rig.sim.facemill_independent)",
    )  # fmt: skip

    @model_validator(mode="before")
    @classmethod
    def _no_stand_in_chatter(cls, data: Any) -> Any:
        old = sorted(k for k in data if k in _REMOVED_CHATTER) if isinstance(data, dict) else []
        if old:
            raise ValueError(
                f"{old[0]} is no longer a setting: the simulated rig chatters where the tool's "
                "modes make the cut unstable ([[tools.NAME.modes]] or [[sim.tool_modes]]: axis, "
                "f_hz, zeta, k_N_m) and the feed limit is the tool's max_chip_mm"
            )
        return data


_REMOVED_CHATTER = ("chatter_fz_mm", "chatter_gain", "chatter_hz")


class SuspenderSection(Model):
    """Conditions that stop a run on their own (Bluesky's suspenders)."""

    force_limit_n: float | None = Field(None, gt=0, le=1e6, description="N, resultant force")
    on_force: Literal["hold", "abort"] = Field(
        "hold", description="feed hold, then abort after hold_timeout_s; or abort at once"
    )
    hold_timeout_s: float = Field(0.0, ge=0, le=3600, description="s held before aborting")
    on_overflow: Literal["fail", "continue"] = Field("fail", description="DAQ overflow")
    on_chatter: Literal["none", "hold", "abort"] = Field(
        "none", description="chatter in the live force (analysis.chatter): none, feed hold "
        "(then abort after hold_timeout_s) or abort at once"
    )
    chatter_floor_n: float = Field(
        10.0, gt=0, le=1e5, description="N, mean resultant a revolution needs to count as cutting"
    )
    stop_campaign_on_fail: bool = Field(False, description="stop the campaign after a failed run")
    watchdog_wall_s: float = Field(
        10.0,
        gt=0,
        le=3600,
        description="s of wall time, beyond twice the program's time plus "
        "30 s, before a run whose program has not ended is declared hung",
    )


class ChatterSection(Model):
    """How chatter is judged, in the report's verdicts and by the ``on_chatter`` suspender
    (:class:`analysis.chatter.ChatterSettings`; defaults: the detector's)."""

    energy_ratio: float = Field(0.1, gt=0, lt=1, description="share of AC energy off harmonics")
    opr_ratio: float = Field(0.2, gt=0, lt=1, description="once-per-rev variance / variance")
    growth_ratio: float = Field(0.8, gt=0, description="off-harmonic RMS, last / first third")
    cut_fraction: float = Field(0.5, gt=0, lt=1, description="where a revolution counts as cut")

    def settings(self):  # noqa: ANN201 - analysis.chatter.ChatterSettings
        from analysis.chatter import ChatterSettings

        return ChatterSettings(self.energy_ratio, self.opr_ratio, cut_fraction=self.cut_fraction,
                               growth_ratio=self.growth_ratio)  # fmt: skip


class FeedRuleSection(Model):
    """A feed rule derived for the campaign (seed 001 4.2 step 3), used by post-processed tests
    with ``rule = "campaign"``. The reference load is a slot of ``reference_depth_mm`` with the
    campaign's tool: the cut known safe at the base feed."""

    min_feed_mm_min: float = Field(100.0, gt=0, description="mm/min")
    base_feed_mm_min: float = Field(1000.0, gt=0, description="mm/min")
    max_feed_mm_min: float = Field(3500.0, gt=0, description="mm/min")
    reference_depth_mm: float = Field(gt=0, description="mm, slot depth loaded at base feed")
    exponent: float = Field(1.0, gt=0, le=5, description="feed ~ load^-exponent")
    n_bins: int = Field(20, ge=3, le=100, description="count")
    min_piece_mm: float = Field(2.0, gt=0, le=100, description="mm, shortest split piece")

    @model_validator(mode="after")
    def _ordered(self) -> FeedRuleSection:
        # The rule is derived after the cuts (feed-rule analysis): a wrong one must stop here.
        lo, base, hi = self.min_feed_mm_min, self.base_feed_mm_min, self.max_feed_mm_min
        if not lo <= base <= hi or lo == hi:
            raise ValueError(
                f"min_feed_mm_min = {lo:g}, base_feed_mm_min = {base:g}, max_feed_mm_min = "
                f"{hi:g}: expected min <= base <= max and min < max (mm/min)"
            )
        return self


class TapTestSection(Model):
    """An impulse-hammer test of the tool, x then y, before the cuts; the stability-sweep
    analysis takes the tool's modes from it. On the simulated rig the twin's tool modes are
    tapped (rig.sim.tap); on a real rig give the two records (`analyze modal` files)."""

    response: Literal["disp", "accel"] = Field("disp", description="tool-tip sensor: disp, accel")
    hits: int = Field(5, ge=2, le=50, description="count of hammer hits per direction")
    rate_hz: float = Field(51_200.0, ge=5_000, le=1e6, description="Hz, tap record rate")
    noise: float = Field(0.002, ge=0, le=0.2, description="sim: response noise / its peak")
    files: dict[str, str] = Field(
        {}, description="real rig: the records per direction, x and y (paths beside the file)"
    )

    @model_validator(mode="after")
    def _directions(self) -> TapTestSection:
        bad = sorted(set(self.files) - {"x", "y"})
        if bad:
            raise ValueError(f"files.{bad[0]}: expected directions x and y")
        return self


class AnalysisSection(Model):
    kind: Literal[
        "none", "facemill-coefficients", "feed-rule", "afc-compare", "stability-sweep"
    ] = "none"
    identify_groups: tuple[str, ...] = ()
    validate_groups: tuple[str, ...] = ()
    rule_name: str = Field("derived", description="name of a derived feed rule")
    compare_groups: tuple[str, ...] = Field((), description="afc-compare: constant, adjusted")
    cv_ratio_target: float = Field(
        1 / 3, gt=0, le=1, description="afc-compare: force CV adjusted / constant at most"
    )
    time_saving_target_pct: float = Field(
        30.0, ge=0, lt=100, description="%, afc-compare: cutting time saving at least"
    )
    stability_method: Literal["sd", "zoa"] = Field(
        "sd", description="stability-sweep: lobes by semi-discretization or ZOA"
    )
    onset_tolerance_pct: float = Field(
        10.0, gt=0, le=100, description="%, stability-sweep: observed onset vs prediction"
    )


class MatrixEntry(Model):
    """A group of tests: the product of every list-valued field."""

    group: str = Field("main", min_length=1, pattern=r"^[A-Za-z0-9_.-]+$")
    fz_mm: FloatOrList | None = Field(None, description="mm/tooth")
    feed_mm_min: FloatOrList | None = Field(None, description="mm/min (instead of fz_mm)")
    depth_mm: FloatOrList | None = Field(None, description="mm, axial depth of cut")
    width_mm: FloatOrList | None = Field(None, description="mm, radial width of cut")
    spindle_rpm: FloatOrList = Field(description="rpm")
    feed_mode: FeedMode | list[FeedMode] = "constant"
    rule: str | None = Field(
        None, description='feed rule for post-processed tests: a rule TOML, or "campaign"'
    )
    repeat: int = Field(1, ge=1, le=100, description="count")

    @model_validator(mode="after")
    def _feed(self) -> MatrixEntry:
        if (self.fz_mm is None) == (self.feed_mm_min is None):
            raise ValueError("give exactly one of fz_mm (mm/tooth) and feed_mm_min (mm/min)")
        for name in ("fz_mm", "feed_mm_min", "depth_mm", "width_mm", "spindle_rpm"):
            v = getattr(self, name)
            vals = v if isinstance(v, list) else [v]
            if isinstance(v, list) and not v:
                raise ValueError(f"{name} = []: give at least one value")
            bad = [x for x in vals if x is not None and not x > 0]
            if bad:
                raise ValueError(f"{name} = {bad[0]}: must be > 0")
        return self


class AdaptiveSection(Model):
    """Closed-loop machining (rig.adaptive, GRBL only): real-time overrides from the live force
    for the runs of ``groups`` (all runs when empty); the other runs are the baseline."""

    mode: Literal["feed", "spindle", "both"] = Field("feed", description="feed, spindle or both")
    groups: tuple[str, ...] = Field((), description="matrix groups under the loop (empty: all)")
    target_force_n: float | None = Field(
        None, gt=0, le=1e6, description="N, per-revolution mean |Fxy| held (default: [feed_rule])"
    )
    max_force_n: float | None = Field(
        None, gt=0, le=1e6,
        description="N, resultant -> feed hold (the lowest of it, the tool's, force_limit_n)",
    )
    dead_band_pct: float = Field(5.0, ge=0, le=50, description="%, of the target")
    slew_up_pct: int = Field(10, ge=1, le=190, description="%, feed override up per revolution")
    slew_down_pct: int = Field(50, ge=1, le=190, description="%, feed override down per rev")
    settle_revs: int = Field(1, ge=0, le=100, description="revolutions after a change")
    air_force_n: float = Field(30.0, gt=0, le=1e5, description="N, below: air (overrides 100 %)")
    stall_revs: float = Field(3.0, gt=0, le=1000, description="revolutions without a DAQ block")
    chatter_revs: int = Field(20, ge=4, le=200, description="revolutions the chatter check judges")
    min_pct: int = Field(10, ge=10, le=100, description="%, lowest override")
    max_pct: int = Field(200, ge=100, le=200, description="%, highest override")
    sim_signal_loss_at_s: float | None = Field(
        None, gt=0, description="sim: s after the program starts the controller hears no more"
    )

    @model_validator(mode="after")
    def _below_max(self) -> AdaptiveSection:
        t, mx = self.target_force_n, self.max_force_n
        if t is not None and mx is not None and not t < mx:
            raise ValueError(
                f"target_force_n = {self.target_force_n:g}, max_force_n = {self.max_force_n:g}: "
                "expected target < max (N)"
            )
        return self


class CampaignFile(Model):
    campaign: CampaignSection
    program: ProgramSection
    daq: DaqOverride = DaqOverride()
    sim: SimSection = SimSection()
    tap_test: TapTestSection | None = None
    suspenders: SuspenderSection = SuspenderSection()
    chatter: ChatterSection = ChatterSection()
    analysis: AnalysisSection = AnalysisSection()
    feed_rule: FeedRuleSection | None = None
    adaptive: AdaptiveSection | None = None
    matrix: tuple[MatrixEntry, ...] = ()
    tests: tuple[MatrixEntry, ...] = ()

    @model_validator(mode="after")
    def _some_tests(self) -> CampaignFile:
        if not self.matrix and not self.tests:
            raise ValueError("no tests: add a [[matrix]] or [[tests]] table")
        return self


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

    def as_dict(self) -> dict[str, Any]:
        return {k: v for k, v in self.__dict__.items() if k != "source_line"}


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
    return tool.inserts if isinstance(tool, FaceMill) else tool.flutes


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
        width_default = tool.diameter_mm if isinstance(tool, EndMill) else block_width_mm
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

    depth_limit = tool.depth_limit_mm if isinstance(tool, FaceMill) else tool.flute_length_mm
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
                kind = "usable insert edge" if isinstance(tool, FaceMill) else "flute length"
                add(t, fields, f"depth_mm = {d:g} is beyond the {kind} of tool "
                    f"'{program_tool(tool)}' ({depth_limit:.3g} mm)", steps)  # fmt: skip
        if isinstance(tool, EndMill) and t.width_mm > tool.diameter_mm + 1e-9:
            add(t, ("width_mm",), f"width_mm = {t.width_mm:g} exceeds the tool diameter "
                f"{tool.diameter_mm:g} mm (one pass cuts at most a slot)")  # fmt: skip
        if t.width_mm == t.width_mm and t.width_mm > program.block_width_mm + 1e-9:
            add(t, ("width_mm",), f"width_mm = {t.width_mm:g} exceeds program.block_width_mm = "
                f"{program.block_width_mm:g} mm")  # fmt: skip
        if t.feed_mode == "post-processed" and not t.rule:
            add(t, ("feed_mode",), "feed_mode = 'post-processed' needs rule = 'FILE' (a rule)")
    problems = [f"{place}: {_which(ts)}: {msg}" for (place, msg), ts in found.items()]
    if isinstance(tool, FaceMill) and program.kind != "facemill-pass":
        problems.append(
            f"{where}: program.kind = '{program.kind}' needs an end mill, got a face mill"
        )
    if isinstance(tool, EndMill) and program.kind == "facemill-pass":
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


def _field_line(text: str, table_line: int, field: str) -> int:
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
        need = "facemill" if isinstance(tool, FaceMill) else "endmill"
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


_ANALYSIS_TOOL = {"facemill-coefficients": FaceMill, "feed-rule": EndMill, "afc-compare": EndMill,
                  "stability-sweep": EndMill}  # fmt: skip


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
    if need is not None and tool is not None and not isinstance(tool, need):
        kind = "a face mill" if need is FaceMill else "an end mill"
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

"""The campaign TOML's tables as validated models (pydantic): one class per table, the whole file
as :class:`CampaignFile`. What they mean together (the matrix, the checks) is
:mod:`rig.campaign.config`."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Literal

from pydantic import Field, model_validator

from analysis.config import ToolMode
from analysis.validation import Model

if TYPE_CHECKING:
    from analysis.chatter import ChatterSettings

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
        None, description="the tool's modes for the regenerative twin (default: the twin's "
        "own structure for the tool, rig/sim/structure.toml)",
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
                "modes make the cut unstable (rig/sim/structure.toml or [[sim.tool_modes]]: axis, "
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

    def settings(self) -> ChatterSettings:
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

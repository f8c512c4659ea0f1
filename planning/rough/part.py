"""Validated part configs for roughing (``configs/parts/*.toml``).

A part file says what to cut (the finished surface: a height field, a grid of points or an STL
mesh), from what (a stock box), with which tool (a name in ``configs/tools.toml``), at what
cutting data, and the roughing limits (finish allowance, allowed cusp, level step). It is checked
with the same pydantic helpers as every other cutlab config, so an error names the file, the line,
the field, the value and the unit, e.g.::

    configs/parts/seed000-bump.toml:41: rough.cusp_mm = 0: Input should be greater than 0 (mm)
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from analysis.config import EndMill, FaceMill, get_tool
from analysis.errors import ConfigError
from analysis.forces import ENDMILL
from analysis.validation import Model, find_line, load_model
from planning.surface import FergusonSurface


class SurfaceSpec(Model):
    """The finished part surface.

    kind = "height_field": ``z_mm[i][j]`` at ``(x_mm[i], y_mm[j])``;
    kind = "grid": ``points_mm[i][j] = [x, y, z]``;
    kind = "stl": ``file`` (relative to the part file) sampled every ``spacing_mm``.
    """

    kind: Literal["height_field", "grid", "stl"]
    x_mm: list[float] | None = Field(None, description="mm, grid x positions")
    y_mm: list[float] | None = Field(None, description="mm, grid y positions")
    z_mm: list[list[float]] | None = Field(None, description="mm, heights, one row per x")
    points_mm: list[list[list[float]]] | None = Field(None, description="mm, [x, y, z] grid")
    file: str | None = Field(None, description="STL file, relative to the part file")
    spacing_mm: float = Field(2.0, gt=0, le=100, description="mm, STL sampling step")

    @model_validator(mode="after")
    def _complete(self) -> SurfaceSpec:
        need = {"height_field": ("x_mm", "y_mm", "z_mm"), "grid": ("points_mm",), "stl": ("file",)}
        missing = [k for k in need[self.kind] if getattr(self, k) is None]
        if missing:
            raise ValueError(f"kind = {self.kind!r} needs {', '.join(missing)}")
        return self


class Stock(Model):
    """The stock box, mm, in the part's coordinates (the program's work coordinates)."""

    x_min_mm: float = Field(description="mm")
    x_max_mm: float = Field(description="mm")
    y_min_mm: float = Field(description="mm")
    y_max_mm: float = Field(description="mm")
    z_min_mm: float = Field(description="mm")
    z_max_mm: float = Field(description="mm")

    @model_validator(mode="after")
    def _ordered(self) -> Stock:
        for a in "xyz":
            lo, hi = getattr(self, f"{a}_min_mm"), getattr(self, f"{a}_max_mm")
            if not hi > lo:
                raise ValueError(f"{a}_max_mm ({hi}) must be greater than {a}_min_mm ({lo})")
        return self


class ToolSpec(Model):
    name: str = Field(min_length=1, description="tool name in the tool library")
    library: str | None = Field(None, description="tool library file (default configs/tools.toml)")
    max_depth_mm: float | None = Field(
        None, gt=0, le=500, description="mm, deepest level cut L (default: flute length)"
    )


class Cutting(Model):
    # >= 1 mm/min: below that a value is more likely a feed per tooth (mm) than a table feed.
    feed_mm_min: float = Field(ge=1, le=100_000, description="mm/min, not mm/tooth")
    spindle_rpm: float = Field(gt=0, le=100_000, description="rpm")
    plunge_feed_mm_min: float | None = Field(
        None, ge=1, le=100_000, description="mm/min (default: half the feed)"
    )
    rapid_mm_min: float = Field(10_000.0, gt=0, le=200_000, description="mm/min, for time")
    material: str | None = Field(
        None, min_length=1, description="workpiece material (configs/materials.toml): limits"
    )


class Rough(Model):
    """Roughing limits and path settings (seed 000 2.4-2.5)."""

    finish_allowance_mm: float = Field(gt=0, le=20, description="mm, offset d of the surface")
    cusp_mm: float = Field(gt=0, le=100, description="mm, allowed shoulder (cusp) height")
    # lower bounds keep the work finite: candidates, offsets and contour points scale with 1/x
    dh_mm: float = Field(0.5, ge=0.01, le=20, description="mm, candidate level spacing")
    first_offset_factor: float = Field(
        1.0, ge=1.0, le=5, description="x tool radius, first offset of the reference contour"
    )
    step_factor: float = Field(
        1.5, ge=0.1, le=2.0, description="x tool radius, further offsets (<= 2 leaves no ridge)"
    )
    ramp_angle_deg: float = Field(5.0, ge=0.5, le=90, description="deg, entry ramp angle")
    clearance_mm: float = Field(5.0, gt=0, le=200, description="mm, above material for moves")
    contour_tolerance_mm: float = Field(0.01, ge=0.001, le=1, description="mm, contour accuracy")
    optimal_dh_mm: float = Field(1.0, ge=0.05, le=20, description="mm, optimal planner grid")
    objective: Literal["path", "time"] = Field("path", description="optimal planner objective")
    cusp_model: Literal["paper", "exact"] = Field(
        "paper", description="shoulder cusp: paper's (h1 - h2) cos(beta), or measured distance"
    )
    lee_factor: float = Field(3.0, ge=1, le=20, description="x cusp, Lee's first-tool step")
    lee_second_tool: str | None = Field(None, description="Lee's second tool (default: same)")
    arc_fit_tol_mm: float = Field(
        0.01,
        ge=0,
        le=1,
        description="mm, G2/G3 arcs where a pass follows a circle within this (0 = lines only)",
    )


class PartConfig(Model):
    name: str = Field(min_length=1)
    description: str = ""
    surface: SurfaceSpec
    stock: Stock
    tool: ToolSpec
    cutting: Cutting
    rough: Rough


class Part:
    """A loaded part: config plus the fitted surface and tools, ready for planning."""

    def __init__(self, config: PartConfig, path: Path | None = None):
        self.config = config
        self.path = path
        where = str(path) if path else f"part {config.name}"
        self.where = where
        lib = self._lib(config.tool.library)
        tool = self._tool(config.tool.name, lib, ("tool", "name"))
        if not ENDMILL.describes(tool) or tool.kind != "flat":
            raise ConfigError(
                f"{where}: tool.name = {config.tool.name!r} is a {getattr(tool, 'kind', '?')} "
                "tool: Z-level roughing (seed 000) needs a flat end mill"
            )
        self.tool: EndMill = tool
        second = config.rough.lee_second_tool
        lee = tool if second is None else self._tool(second, lib, ("rough", "lee_second_tool"))
        if not ENDMILL.describes(lee) or lee.kind != "flat":
            raise ConfigError(f"{where}: rough.lee_second_tool = {second!r}: needs a flat end mill")
        self.lee_tool: EndMill = lee
        self.surface = self._surface(config.surface, f"{where}: surface")

    def _tool(self, name: str, lib: Path | None, loc: tuple[str, str]) -> EndMill | FaceMill:
        """The named tool; an unknown name is reported at its line of the part file."""
        try:
            return get_tool(name, lib)
        except ConfigError as exc:
            line = None
            if self.path is not None and self.path.exists():
                line = find_line(self.path.read_text(encoding="utf-8"), loc)
            at = f"{self.where}:{line}" if line else self.where
            raise ConfigError(f"{at}: {'.'.join(loc)} = {name!r}: {exc}") from None

    def _lib(self, library: str | None) -> Path | None:
        if library is None:
            return None
        p = Path(library)
        return p if p.is_absolute() or self.path is None else self.path.parent / p

    def _surface(self, spec: SurfaceSpec, where: str) -> FergusonSurface:
        if spec.kind == "height_field":
            z = spec.z_mm
            assert z is not None  # SurfaceSpec's validator: a height field has z_mm
            if len({len(r) for r in z}) != 1:
                raise ConfigError(f"{where}: surface.z_mm rows have different lengths (mm)")
            return FergusonSurface.from_height_field(
                np.array(spec.x_mm), np.array(spec.y_mm), np.array(z, float), where=where
            )
        if spec.kind == "grid":
            try:
                pts = np.array(spec.points_mm, dtype=float)
            except ValueError:
                raise ConfigError(
                    f"{where}: surface.points_mm is ragged: every row needs the same count of "
                    "[x, y, z] points (mm)"
                ) from None
            return FergusonSurface.from_points(pts, where=where)
        file = self._lib(spec.file)
        assert file is not None
        return FergusonSurface.from_stl(file, spec.spacing_mm)

    @property
    def max_depth_mm(self) -> float:
        """The tool's maximum depth of cut L, mm."""
        return self.config.tool.max_depth_mm or self.tool.flute_length_mm


def load_part(path: str | Path) -> Part:
    """Load and check a part file; ConfigError/PlanningError name file, field, value and unit."""
    p = Path(path)
    if not p.exists() and p.suffix != ".toml":
        from analysis.config import config_dir

        cand = config_dir() / "parts" / f"{path}.toml"
        if not cand.exists():
            known = sorted(q.stem for q in (config_dir() / "parts").glob("*.toml"))
            raise ConfigError(f"part '{path}' not found: not a file, and not one of {known}")
        p = cand
    return Part(load_model(PartConfig, p), p)

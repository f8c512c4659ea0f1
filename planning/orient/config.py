"""The config of a 5-axis orientation job (``configs/orient/*.toml``), validated with pydantic.

One file holds the part (NURBS surfaces: the machined one and its neighbours, e.g. the two impeller
blades), the CC paths (iso-parameter lines of the machined surface), the tool (by name from the tool
library), the machine for the NC output, the angle limits and the planner settings. Errors go
through :func:`analysis.validation.validate`, so they name file, line, field, value and unit::

    configs/orient/impeller.toml:12: limits.alpha_deg = (0.0, 95.0): ... (deg)
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from analysis.config import (
    EndMill,
    MachineConfig,
    get_tool,
    load_machine,
)
from analysis.errors import ConfigError
from analysis.forces import ENDMILL
from analysis.validation import Model, read_toml, validate
from planning.surface import NurbsSurface


class SurfaceSpec(Model):
    """One NURBS surface: control net, knots, optional weights."""

    name: str = Field(min_length=1)
    role: Literal["machined", "check"] = Field(description="machined surface or neighbour")
    degree: tuple[int, int] = Field((3, 3), description="polynomial degree in u and v")
    knots_u: tuple[float, ...] | None = Field(None, description="full knot vector (clamped)")
    knots_v: tuple[float, ...] | None = Field(None, description="full knot vector (clamped)")
    control_points_mm: tuple[tuple[tuple[float, float, float], ...], ...] = Field(
        description="mm, rows along u, each a list of [x, y, z] along v"
    )
    weights: tuple[tuple[float, ...], ...] | None = Field(None, description="> 0, like the net")
    flip_normal: bool = Field(False, description="flip S_u x S_v so the normal faces the tool")

    @model_validator(mode="after")
    def _shape(self) -> SurfaceSpec:
        rows = {len(r) for r in self.control_points_mm}
        if len(rows) != 1:
            raise ValueError(f"control_points_mm rows have different lengths {sorted(rows)}")
        nu, nv = len(self.control_points_mm), rows.pop()
        p, q = self.degree
        if not (1 <= p < nu and 1 <= q < nv):
            raise ValueError(
                f"degree {self.degree} needs more than that many control points; net is {nu} x {nv}"
            )
        for label, k, n, d in (("knots_u", self.knots_u, nu, p), ("knots_v", self.knots_v, nv, q)):
            if k is not None and len(k) != n + d + 1:
                raise ValueError(f"{label} has {len(k)} knots, expected {n + d + 1}")
        if self.weights is not None:
            if len(self.weights) != nu or any(len(r) != nv for r in self.weights):
                raise ValueError(f"weights must be {nu} x {nv} like control_points_mm")
            if min(min(r) for r in self.weights) <= 0:
                raise ValueError("weights must all be > 0")
        return self

    def build(self) -> NurbsSurface:
        from planning.surface.nurbs import clamped_uniform_knots

        cp = np.asarray(self.control_points_mm, float)
        p, q = self.degree
        ku = np.asarray(self.knots_u) if self.knots_u else clamped_uniform_knots(cp.shape[0], p)
        kv = np.asarray(self.knots_v) if self.knots_v else clamped_uniform_knots(cp.shape[1], q)
        w = None if self.weights is None else np.asarray(self.weights, float)
        return NurbsSurface((p, q), ku, kv, cp, w, -1 if self.flip_normal else 1, self.name)


class PathSpec(Model):
    """CC paths: iso-parameter lines of the machined surface (seed 002 section 5)."""

    along: Literal["u", "v"] = Field("u", description="parameter that runs along the feed")
    lines: tuple[float, ...] = Field(min_length=1, description="fraction 0..1 of the other range")
    points_per_line: int = Field(10, ge=2, le=10_000, description="count")
    span: tuple[float, float] = Field((0.05, 0.95), description="fraction 0..1 of the feed range")
    zigzag: bool = Field(True, description="reverse every other line")

    @model_validator(mode="after")
    def _fractions(self) -> PathSpec:
        for x in (*self.lines, *self.span):
            if not 0.0 <= x <= 1.0:
                raise ValueError(f"{x} is outside 0..1 (fraction of the parameter range)")
        if not self.span[1] > self.span[0]:
            raise ValueError(f"span {self.span} must be increasing")
        return self


class Limits(Model):
    """Angle limits (seed 002: 0 <= alpha <= 15 deg, -90 <= beta <= 90 deg)."""

    alpha_deg: tuple[float, float] = Field((0.0, 15.0), description="deg, advance angle range")
    beta_deg: tuple[float, float] = Field((-90.0, 90.0), description="deg, tilt angle range")

    @model_validator(mode="after")
    def _ranges(self) -> Limits:
        a0, a1 = self.alpha_deg
        b0, b1 = self.beta_deg
        if not (0.0 <= a0 <= a1 <= 89.0):
            raise ValueError(f"alpha_deg = {self.alpha_deg}: need 0 <= min <= max <= 89 (deg)")
        if not (-90.0 <= b0 <= b1 <= 90.0):
            raise ValueError(f"beta_deg = {self.beta_deg}: need -90 <= min <= max <= 90 (deg)")
        return self


class PlannerSettings(Model):
    """Numbers of the energy, the optimisation and the collision check."""

    charge_spacing_mm: float = Field(0.6, gt=0.01, le=20, description="mm, part charge spacing")
    check_spacing_mm: float = Field(0.3, gt=0.01, le=20, description="mm, check mesh edge length")
    gouge_tolerance_mm: float = Field(0.005, gt=0, le=1, description="mm, allowed overcut")
    clearance_mm: float = Field(1.0, ge=0, le=100, description="mm, holder and nose clearance")
    smoothness_weight: float = Field(
        5.0, ge=0, le=1000, description="per rad^2 of angle change, against R (K - kappa)"
    )
    curvature_margin_per_mm: float = Field(0.0, ge=0, le=10, description="1/mm, K - kappa floor")
    feed_mm_min: float = Field(1000.0, gt=0, le=200_000, description="mm/min")
    spindle_rpm: float = Field(8000.0, gt=0, le=100_000, description="rpm")


class OrientConfig(Model):
    """A 5-axis orientation job."""

    name: str = Field(min_length=1)
    description: str = ""
    tool: str = Field(min_length=1, description="tool name in configs/tools.toml")
    machine: str = Field("mill-5axis", min_length=1, description="machine in configs/machines")
    limits: Limits = Limits()
    planner: PlannerSettings = PlannerSettings()
    paths: PathSpec
    surfaces: tuple[SurfaceSpec, ...] = Field(min_length=1)

    @model_validator(mode="after")
    def _one_machined(self) -> OrientConfig:
        machined = [s.name for s in self.surfaces if s.role == "machined"]
        if len(machined) != 1:
            raise ValueError(f"exactly one surface must have role = 'machined', got {machined}")
        names = [s.name for s in self.surfaces]
        if len(set(names)) != len(names):
            raise ValueError(f"surface names repeat: {names}")
        return self

    @property
    def machined(self) -> SurfaceSpec:
        return next(s for s in self.surfaces if s.role == "machined")


def load_orient(path: str | Path) -> tuple[OrientConfig, EndMill, MachineConfig]:
    """Load and validate an orientation config with its tool and machine."""
    data, text = read_toml(path)
    cfg = validate(OrientConfig, data, str(path), text)
    tool = get_tool(cfg.tool)
    if not ENDMILL.describes(tool):
        raise ConfigError(f"{path}: tool = {cfg.tool!r} is a {tool.kind}: 5-axis needs an end mill")
    machine = load_machine(cfg.machine)
    return cfg, tool, machine

"""Starting stocks from specs and files (:mod:`planning.stock.machining` re-exports them; the
plan file's ``[stock]`` table is read by :mod:`planning.stock.plans`).

Spec: ``box:XMIN,XMAX,YMIN,YMAX,BOTTOM,TOP`` (mm), a mesh file (``.stl``, ``.obj``, ``.ply``,
``.off``), or a TOML file with a ``[stock]`` table (see :mod:`planning.stock.machining`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field

from analysis.validation import Model, read_toml, validate
from planning.errors import PlanningError
from planning.nc import Motion, bounding_box
from planning.stock.zmap import Cutter, ZMap


class _StockModel(Model):
    kind: Literal["box", "mesh", "heights"]
    spacing_mm: float | None = Field(None, gt=0, le=100, description="mm")
    xmin_mm: float | None = Field(None, description="mm")
    xmax_mm: float | None = Field(None, description="mm")
    ymin_mm: float | None = Field(None, description="mm")
    ymax_mm: float | None = Field(None, description="mm")
    bottom_mm: float | None = Field(None, description="mm")
    top_mm: float | None = Field(None, description="mm")
    path: str | None = Field(None, description="mesh or .npy height field, relative to the file")
    margin_mm: float = Field(0.0, ge=0, description="mm")
    x0_mm: float = Field(0.0, description="mm")
    y0_mm: float = Field(0.0, description="mm")


DEFAULT_SPACING_MM = 0.25


def _stock_from_model(st: _StockModel, where: str, base: Path, spacing_mm: float | None) -> ZMap:
    s = spacing_mm or st.spacing_mm or DEFAULT_SPACING_MM
    if st.kind == "box":
        need = ("xmin_mm", "xmax_mm", "ymin_mm", "ymax_mm", "bottom_mm", "top_mm")
        missing = [k for k in need if getattr(st, k) is None]
        if missing:
            raise PlanningError(f"{where}: stock kind 'box' needs {', '.join(missing)} (mm)")
        # arg-type: the six are not None past the check above (getattr hides that from mypy)
        return ZMap.box(st.xmin_mm, st.xmax_mm, st.ymin_mm, st.ymax_mm, st.bottom_mm, st.top_mm, s)  # type: ignore[arg-type]
    if st.path is None:
        raise PlanningError(f"{where}: stock kind '{st.kind}' needs path")
    p = Path(st.path) if Path(st.path).is_absolute() else base / st.path
    if not p.exists():
        raise PlanningError(f"{where}: stock path = {st.path!r}: file {p} not found")
    if st.kind == "mesh":
        return ZMap.from_mesh(p, s, st.margin_mm, st.bottom_mm)
    try:
        h = np.load(p)
    except Exception as exc:  # numpy raises several types for a bad file
        raise PlanningError(f"{where}: {p}: not a .npy height field: {exc}") from None
    return ZMap.from_heights(h, st.x0_mm, st.y0_mm, s, st.bottom_mm)


def load_stock(
    spec: str | Path,
    spacing_mm: float | None = None,
) -> ZMap:
    """The starting stock from a spec (see the module docstring)."""
    text = str(spec)
    if text.startswith("box:"):
        try:
            vals = [float(v) for v in text[4:].split(",")]
        except ValueError:
            vals = []
        if len(vals) != 6:
            raise PlanningError(
                f"stock {text!r}: expected box:XMIN,XMAX,YMIN,YMAX,BOTTOM,TOP (six numbers, mm)"
            )
        x0, x1, y0, y1, bottom, top = vals
        return ZMap.box(x0, x1, y0, y1, bottom, top, spacing_mm or DEFAULT_SPACING_MM)
    p = Path(text)
    if not p.exists():
        raise PlanningError(
            f"stock {text!r}: no such file (or use box:XMIN,XMAX,YMIN,YMAX,BOTTOM,TOP)"
        )
    if p.suffix.lower() in (".stl", ".obj", ".ply", ".off"):
        return ZMap.from_mesh(p, spacing_mm or DEFAULT_SPACING_MM)
    data, raw = read_toml(p)
    if "stock" not in data:
        raise PlanningError(f"{p}: no [stock] table")
    st = validate(_StockModel, data["stock"], str(p), raw)
    return _stock_from_model(st, str(p), p.parent, spacing_mm)


def default_stock(motion: Motion, cutter: Cutter, spacing_mm: float | None = None) -> ZMap:
    """A box over the program's feed moves (XY extent plus the cutter radius), top at Z = 0
    (work zero on the stock top, the usual convention), bottom 1 mm below the deepest feed move
    (arcs' bulges included: a G18/G19 arc dips below its end points).
    """
    feed = motion.is_feed
    if not feed.any():
        raise PlanningError("the program has no feed moves: give the stock (--stock)")
    r = cutter.radius_mm
    lo, hi = bounding_box(motion[feed])
    bottom = min(float(lo[2]) - 1.0, -1.0)
    return ZMap.box(
        float(lo[0]) - r, float(hi[0]) + r, float(lo[1]) - r, float(hi[1]) + r, bottom, 0.0,
        spacing_mm or DEFAULT_SPACING_MM,
    )  # fmt: skip

"""The Z-level roughing plan as `cutlab plan rough` prints it: the chosen method's levels (seed
000 Table 1), the totals of every method side by side, and the Z-map check."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from analysis.output import table_lines

__all__ = ["LEVEL_COLUMNS", "rough_lines"]

# the per-level table (seed 000 Table 1): column -> key of a level row
LEVEL_COLUMNS = {"order": "order", "z_mm": "z_mm", "area_mm2": "area_mm2", "path_mm": "path_mm",
                 "h_mm": "height_mm", "MRR_mm3_min": "mrr_mm3_min",
                 "A*h/l_mm2": "mrr_per_path_mm2"}  # fmt: skip


def rough_lines(res_json: Mapping[str, object], method: str) -> list[str]:
    """:func:`planning.rough.run_rough`'s result as lines (the limits' part apart:
    :mod:`planning.limits.text`)."""
    res: Any = res_json  # the job's JSON result, read by key
    c = res["check"]
    out: list[str] = []
    out.append(
        f"{res['part']}: {method} levels (seed 000 Table 1 columns), cusp model "
        f"{res['cusp_model']}, program for {res['dialect']}"
    )
    out += table_lines([{k: r[v] for k, v in LEVEL_COLUMNS.items()} for r in res["levels"]], ".2f")
    out.append("\ntotals by method (same cusp limit and depth limit)")
    out += table_lines(
        [
            {"method": m, **{k: v for k, v in t.items() if k != "heights_mm"}}
            for m, t in res["totals"].items()
        ],
        ".2f",
    )
    out.append("")
    for k, v in res["comparison"].items():
        out.append(f"{k}: {v} %")
    if c is not None:
        out.append(
            f"Z-map check ({c['spacing_mm']} mm grid, tolerance {c['tolerance_mm']} mm): max "
            f"left {c['max_left_mm']} mm (cusp limit {c['cusp_limit_mm']} + tolerance), "
            f"vertical {c['max_left_vertical_mm']} mm, gouge {c['max_gouge_mm']} mm (at most the "
            f"tolerance), rapids into material {c['rapid_removed_mm3']} mm3: "
            f"{'OK' if c['ok'] else 'FAILED'}"
        )
    return out

"""`cutlab plan rough CONFIG [--method M] -o OUT.nc [--json]`: Z-level roughing (seed 000).

Plans the part by every method (bisection, equal, lee, optimal) under the same cusp and depth
limits, writes the chosen method's program to OUT.nc (through planning.nc's writer), prints the
per-level table of the chosen method (as seed 000 Table 1) and the totals of all methods side by
side, then cuts the written program on a Z-map and reports the material left above the offset
surface and any gouge. Pictures (unless --no-png), next to OUT.nc: OUT.levels.png (levels of all
methods in a side view), OUT.paths.png (passes of the chosen method), OUT.roughed.png (the
roughed Z-map and the material left).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``rough`` to the ``plan`` group."""
    p = sub.add_parser(
        "rough",
        help="Z-level roughing: levels by bisection for maximum removal rate (seed 000)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("config", help="part file, e.g. configs/parts/seed000-bump.toml (or its name)")
    p.add_argument(
        "--method", choices=("bisection", "equal", "lee", "optimal"), default="bisection"
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="NC program to write")
    p.add_argument("--json", action="store_true", help="print everything as JSON")
    p.add_argument(
        "--cusp-model",
        choices=("paper", "exact"),
        default=None,
        help="override rough.cusp_model (paper: (h1-h2)cos(beta); exact: measured distance)",
    )
    p.add_argument("--no-png", action="store_true", help="skip the pictures")
    p.add_argument("--no-check", action="store_true", help="skip the Z-map check")
    p.add_argument(
        "--check-spacing", type=float, default=0.5, help="Z-map grid spacing of the check, mm"
    )
    p.set_defaults(func=run)


def _shorter_pct(a: float, b: float) -> float | None:
    """How much shorter a is than b, % of b."""
    return round(100.0 * (1.0 - a / b), 2) if b else None


def _comparison(totals: dict) -> dict:
    path = {m: t["cutting_path_mm"] for m, t in totals.items()}
    return {
        "bisection_shorter_than_equal_pct": _shorter_pct(path["bisection"], path["equal"]),
        "bisection_shorter_than_lee_pct": _shorter_pct(path["bisection"], path["lee"]),
        "optimal_shorter_than_bisection_pct": _shorter_pct(path["optimal"], path["bisection"]),
    }


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from planning.errors import PlanningError
    from planning.rough import Part, RoughPlanner, check_program, load_part
    from planning.rough.gcode import MoveSettings, plan_motion, plan_program, plan_totals
    from rig.cli._common import print_json, print_table, status

    if not args.check_spacing > 0:
        raise PlanningError(f"--check-spacing = {args.check_spacing}: must be > 0 (mm)")
    part = load_part(args.config)
    if args.cusp_model is not None:
        cfg = part.config
        rough = cfg.rough.model_copy(update={"cusp_model": args.cusp_model})
        part = Part(cfg.model_copy(update={"rough": rough}), part.path)
    t0 = time.perf_counter()
    with tqdm(desc="plan rough", unit="step", file=sys.stderr, leave=False, disable=None) as bar:

        def progress(msg: str) -> None:
            bar.set_postfix_str(msg, refresh=False)
            bar.update()

        planner = RoughPlanner(part, progress=progress)
        plans = planner.plan_all()
    status(f"planned 4 methods in {time.perf_counter() - t0:.1f} s")
    motions = {m: plan_motion(p, part) for m, p in plans.items()}
    totals = {m: plan_totals(p, part, motions[m]) for m, p in plans.items()}
    chosen = plans[args.method]
    program = plan_program(chosen, part, motions[args.method])
    args.output.parent.mkdir(parents=True, exist_ok=True)
    program.write(args.output)
    status(f"wrote {args.output} ({len(program.lines)} lines)")

    check = None
    if not args.no_check:
        st = part.config.stock
        check = check_program(
            program.text(),
            planner.offset_surface,
            (st.x_min_mm, st.x_max_mm, st.y_min_mm, st.y_max_mm, st.z_min_mm, st.z_max_mm),
            {1: part.tool.radius_mm, 2: part.lee_tool.radius_mm},
            part.config.rough.cusp_mm,
            MoveSettings.of(part).safe_z_mm,
            spacing_mm=args.check_spacing,
        )
    pngs = {}
    if not args.no_png:
        from planning.rough.plot import plot_levels, plot_paths, plot_roughed

        stem = args.output.with_suffix("")
        pngs["levels"] = str(plot_levels(planner, plans, f"{stem}.levels.png"))
        pngs["paths"] = str(plot_paths(planner, chosen, f"{stem}.paths.png"))
        if check is not None:
            pngs["roughed"] = str(plot_roughed(check, args.method, f"{stem}.roughed.png"))

    result = {
        "part": part.config.name,
        "method": args.method,
        "cusp_model": part.config.rough.cusp_model,
        "cusp_mm": part.config.rough.cusp_mm,
        "max_depth_mm": planner.L,
        "bottom_mm": round(planner.bottom, 4),
        "top_mm": planner.top,
        "levels": [lv.row() for lv in chosen.levels],
        "totals": totals,
        "comparison": _comparison(totals),
        "check": None if check is None else check.summary(),
        "program": str(args.output),
        "png": pngs,
    }
    if args.json:
        print_json(result)
        return 0 if check is None or check.ok else 1
    print(f"{part.config.name}: {args.method} levels (seed 000 Table 1 columns), cusp model "
          f"{result['cusp_model']}")  # fmt: skip
    print_table(
        [
            {
                "order": r["order"],
                "z_mm": r["z_mm"],
                "area_mm2": r["area_mm2"],
                "path_mm": r["path_mm"],
                "h_mm": r["height_mm"],
                "MRR_mm3_min": r["mrr_mm3_min"],
                "A*h/l_mm2": r["mrr_per_path_mm2"],
            }
            for r in result["levels"]
        ],
        floatfmt=".2f",
    )
    print()
    print("totals by method (same cusp limit and depth limit)")
    print_table(
        [
            {"method": m, **{k: v for k, v in t.items() if k != "heights_mm"}}
            for m, t in totals.items()
        ],
        floatfmt=".2f",
    )
    print()
    for k, v in result["comparison"].items():
        print(f"{k}: {v} %")
    if check is not None:
        c = check.summary()
        print(
            f"Z-map check ({c['spacing_mm']} mm grid, tolerance {c['tolerance_mm']} mm): max "
            f"left {c['max_left_mm']} mm (cusp limit {c['cusp_limit_mm']} + tolerance), "
            f"vertical {c['max_left_vertical_mm']} mm, gouge {c['max_gouge_mm']} mm (at most the "
            f"tolerance), rapids into material {c['rapid_removed_mm3']} mm3: "
            f"{'OK' if c['ok'] else 'FAILED'}"
        )
    for k, v in pngs.items():
        print(f"{k}: {v}")
    return 0 if check is None or check.ok else 1

"""`cutlab analyze stability CONFIG -o lobes.csv [--method sd|zoa] [--steps M] [--json]
[--plot lobes.png]`: milling stability lobes, the chatter-free axial depth per spindle speed.

CONFIG (TOML) holds the tool's teeth, the cut (up/down milling, radial immersion), the cutting
coefficients (or coefficients_file: `cutlab analyze forces --json` output), the tool's modes per
direction (or modes_file: `cutlab analyze modal --save`), and the spindle speeds; see
configs/stability/. The CSV has one row per speed: spindle_rpm, depth_limit_mm, chatter_hz
(empty where the cut is stable up to the deepest depth searched). Methods: sd, semi-
discretization (default: it finds the period-doubling lobes of interrupted cuts), and zoa, the
zero-order approximation, which warns where it misses them.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rig.cli._common import count, image_file


def register_stability(psub: argparse._SubParsersAction) -> None:
    """Add ``stability`` to the ``analyze`` group's subparsers."""
    p = psub.add_parser(
        "stability", help="stability lobes: chatter-free depth per spindle speed",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
    )  # fmt: skip
    p.add_argument("config", help="stability case (TOML), e.g. configs/stability/*.toml")
    p.add_argument("-o", "--output", type=Path, required=True, help="CSV of the lobes to write")
    p.add_argument("--method", choices=("sd", "zoa"), default="sd",
                   help="sd: semi-discretization (default); zoa: zero-order approx.")  # fmt: skip
    p.add_argument("--steps", type=count(4, 400), default=None, metavar="M",
                   help="steps per tooth period of sd (default: the config's, 30)")  # fmt: skip
    p.add_argument(
        "--plot", type=image_file, default=None, metavar="PNG", help="write the lobes plot"
    )
    p.add_argument("--json", action="store_true", help="JSON on stdout")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from analysis.errors import AnalysisError
    from analysis.stability import load_case, plot_lobes, stability_lobes
    from rig.cli._common import print_json, status

    case = load_case(args.config)
    lobes = stability_lobes(case, args.method, args.steps)
    finite = np.isfinite(lobes.depth_limit_mm)
    table = np.column_stack([lobes.spindle_rpm, lobes.depth_limit_mm, lobes.chatter_hz])
    lines = ["spindle_rpm,depth_limit_mm,chatter_hz"] + [
        f"{n:.6g},{a:.6g},{f:.6g}" if ok else f"{n:.6g},," for (n, a, f), ok in zip(table, finite)
    ]
    try:
        args.output.write_text("\n".join(lines) + "\n", encoding="utf-8")
    except OSError as exc:
        raise AnalysisError(f"{args.output}: cannot write the lobes: {exc}") from None
    status(f"analyze stability: wrote {args.output} ({len(table)} speeds)")
    if args.plot:
        status(f"analyze stability: wrote {plot_lobes(lobes, args.plot, case.name)}")
    for w in lobes.warnings:
        status(f"analyze stability: warning: {w}")
    if args.json:
        print_json({"config": str(args.config), "csv": str(args.output), **lobes.to_json()})
        return 0
    rpm, mm = lobes.minimum()
    steps = f", {lobes.steps_per_period} steps per tooth period" if lobes.method == "sd" else ""
    low = f"lowest limit {mm:.4g} mm at {rpm:.0f} rpm" if finite.any() else "no limit found"
    print(f"{case.name}: {lobes.method}{steps}; {low}; {int(finite.sum())} of {finite.size} "
          f"speeds limited below {lobes.depth_max_mm:.4g} mm")  # fmt: skip
    return 0

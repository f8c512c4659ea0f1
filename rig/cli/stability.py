"""`cutlab analyze stability CONFIG -o lobes.csv [--method sd|zoa] [--steps M] [--json]
[--plot lobes.png]`: milling stability lobes, the chatter-free axial depth per spindle speed.

CONFIG (TOML) holds the tool's teeth, the cut (up/down milling, radial immersion), the cutting
coefficients (or coefficients_file: `cutlab analyze forces --json` output), the tool's modes per
direction (or modes_file: `cutlab analyze modal --save`), and the spindle speeds; see
configs/stability/. The CSV has one row per speed: spindle_rpm, depth_limit_mm, chatter_hz, kind
(hopf, flip or stable), steps and convergence_pct; numbers are written round-trip exact, and a
speed stable up to the deepest depth searched (--max-depth, default 30 x the lowest ZOA limit)
reads depth_limit_mm inf, chatter_hz nan, kind stable. Methods: sd, semi-discretization
(default: it finds the period-doubling lobes of interrupted cuts), and zoa, the zero-order
approximation, which warns where it misses them. SD starts at the config's steps per tooth
period (30) and doubles them at each speed until the limit changes by at most 1 % (up to
240; convergence_pct is the last doubling's change, the summary line gives the largest);
--steps M fixes the count instead (no check).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rig.cli.common import count, image_file, positive


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
                   help="fixed steps per tooth period of sd (default: start at the config's, "
                        "30, and double per speed until within 1 %%)")  # fmt: skip
    p.add_argument("--max-depth", type=positive("mm", 1000.0), default=None, metavar="MM",
                   help="deepest cut searched, mm (default: the config's, else 30 x the "
                        "lowest ZOA limit)")  # fmt: skip
    p.add_argument(
        "--plot", type=image_file, default=None, metavar="PNG", help="write the lobes plot"
    )
    p.add_argument("--json", action="store_true", help="JSON on stdout")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import dataclasses
    import math

    import numpy as np

    from analysis.errors import AnalysisError
    from analysis.stability import load_case, plot_lobes, stability_lobes
    from rig.cli.common import print_json, status

    case = load_case(args.config)
    if args.max_depth is not None:
        case = dataclasses.replace(case, depth_max_mm=args.max_depth)
    lobes = stability_lobes(case, args.method, args.steps)
    finite = np.isfinite(lobes.depth_limit_mm)
    steps = lobes.steps if lobes.steps is not None else np.zeros(finite.size, int)
    rel = (lobes.convergence_rel if lobes.convergence_rel is not None
           else np.full(finite.size, np.nan))  # fmt: skip
    lines = ["spindle_rpm,depth_limit_mm,chatter_hz,kind,steps,convergence_pct"] + [
        # repr: the shortest text that reads back as the same float (round-trip exact)
        f"{float(n)!r},{float(a)!r},{float(f) if ok else math.nan!r},{k or 'stable'},"
        f"{int(m) if m > 0 else ''},{float(r * 100)!r}"
        for n, a, f, k, m, r, ok in zip(lobes.spindle_rpm, lobes.depth_limit_mm,
                                        lobes.chatter_hz, lobes.kind, steps, rel, finite)
    ]  # fmt: skip
    try:
        args.output.write_text("\n".join(lines) + "\n", encoding="utf-8")
    except OSError as exc:
        raise AnalysisError(f"{args.output}: cannot write the lobes: {exc}") from None
    status(f"analyze stability: wrote {args.output} ({finite.size} speeds)")
    if args.plot:
        status(f"analyze stability: wrote {plot_lobes(lobes, args.plot, case.name, case)}")
    for w in lobes.warnings:
        status(f"analyze stability: warning: {w}")
    if args.json:
        print_json({"config": str(args.config), "csv": str(args.output), **lobes.to_json()})
        return 0
    rpm, mm = lobes.minimum()
    conv = lobes.convergence()
    if not conv["checked"]:
        how = f", convergence unchecked ({conv['reason']})"
    else:
        how = (f", {lobes.steps_per_period}-{conv['max_steps']} steps per tooth period, "
               f"converged within {conv['max_change_pct']:.2f} % (doubling check)")  # fmt: skip
        if conv["unconverged_speeds"]:
            how = (f", {conv['unconverged_speeds']} speeds NOT converged within 1 % at "
                   f"{conv['max_steps']} steps")  # fmt: skip
    low = f"lowest limit {mm:.4g} mm at {rpm:.0f} rpm" if finite.any() else "no limit found"
    print(f"{case.name}: {lobes.method}{how}; {low}; {int(finite.sum())} of {finite.size} "
          f"speeds limited below {lobes.depth_max_mm:.4g} mm")  # fmt: skip
    return 0

"""`cutlab plan rough CONFIG [--method M] [--dialect D] [--machine M] -o OUT.nc [--json]`: Z-level
roughing (seed 000).

Plans the part by every method (bisection, equal, lee, optimal) under the same cusp and depth
limits, writes the chosen method's program to OUT.nc (through planning.nc's writer) for the
controller's dialect (--dialect fanuc|linuxcnc|grbl; default the --machine's, else fanuc),
prints the per-level table of the chosen method (as seed 000 Table 1) and the totals of all
methods side by side, then cuts the program on a Z-map and reports the material left above the
offset surface and any gouge. Pictures (unless --no-png), next to OUT.nc: OUT.levels.png
(levels of all methods in a side view), OUT.paths.png (passes of the chosen method),
OUT.roughed.png (the roughed Z-map and the material left).

Exit status: 0 when the program is written, the Z-map check passes and the limits' verdict is
'within' or 'unchecked' (the limits not checked are listed); 3 when it is written but the Z-map
check finds a gouge or material left, or a block breaks a limit ('violations'; --limit splits
levels and lowers feeds to cure them); 2 bad input.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rig.cli.common import bar_note, positive, show
from rig.cli.options import LOBES, REQUIRED, command, dialect_row
from rig.terminal import Progress


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``rough`` to the ``plan`` group."""
    command(sub, "rough", "Z-level roughing: levels by bisection for maximum removal rate (seed "
            "000)", ROUGH, run, catalogs=True, description=__doc__,
            formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip


# fmt: off
ROUGH = (
    ("config", None, None, "part file, e.g. configs/parts/seed000-bump.toml (or its name)"),
    ("--method", ("bisection", "equal", "lee", "optimal"), "bisection", None),
    ("-o --output", Path, REQUIRED, "NC program to write"),
    dialect_row("controller to write for (default: the machine's)"),
    ("--machine", None, None, "machine config name or path: its dialect and tool changer "
     "(default: none, fanuc)"),
    ("--json", bool, None, "print everything as JSON"),
    ("--cusp-model", ("paper", "exact"), None, "override rough.cusp_model (paper: (h1-h2)cos(beta);"
     " exact: measured distance)"),
    ("--no-png", bool, None, "skip the pictures"),
    ("--no-check", bool, None, "skip the Z-map check"),
    ("--check-spacing", positive("mm", 100), 0.5, "Z-map grid spacing of the check, mm"),
    ("--limit", bool, None, "split levels or lower feeds until every block is within the "
     "machine's and tool's limits"),
    ("--material", None, None, "workpiece material (default: the part's cutting.material)"),
    LOBES,
)
# fmt: on


def run(args: argparse.Namespace) -> int:
    from planning.limits import rough_limiter
    from planning.limits.text import rough_answer, rough_text
    from planning.rough import run_rough
    from rig.cli.plan_check import WRITTEN_EXIT

    with Progress("plan rough", "step") as bar:  # planned, the bar gives way to the notes
        res = rough_answer(run_rough(
            args.config, args.output, args.method, args.cusp_model, check=not args.no_check,
            check_spacing_mm=args.check_spacing, png=not args.no_png, progress=bar.step,
            status=bar_note(bar), dialect=args.dialect, machine=args.machine,
            limits=rough_limiter(fix=args.limit, machine=args.machine, material=args.material,
                                 lobes=args.lobes),
        ))  # fmt: skip
    c = res["check"]
    code = 3 if c is not None and not c["ok"] else WRITTEN_EXIT[res["verdict"]]
    return show(args.json, res, lambda: rough_text(res), code)

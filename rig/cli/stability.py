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

from rig.cli.common import count, image_file, noter, positive, show
from rig.cli.options import REQUIRED, command, json_row


def register_stability(psub: argparse._SubParsersAction) -> None:
    """Add ``stability`` to the ``analyze`` group's subparsers."""
    command(psub, "stability", "stability lobes: chatter-free depth per spindle speed", [
        ("config", None, None, "stability case (TOML), e.g. configs/stability/*.toml"),
        ("-o --output", Path, REQUIRED, "CSV of the lobes to write"),
        ("--method", ("sd", "zoa"), "sd", "sd: semi-discretization (default); zoa: zero-order "
         "approx."),
        ("--steps", count(4, 400), None, "fixed steps per tooth period of sd (default: start at "
         "the config's, 30, and double per speed until within 1 %%)", {"metavar": "M"}),
        ("--max-depth", positive("mm", 1000.0), None, "deepest cut searched, mm (default: the "
         "config's, else 30 x the lowest ZOA limit)", {"metavar": "MM"}),
        ("--plot", image_file, None, "write the lobes plot", {"metavar": "PNG"}),
        json_row(),
    ], run, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip


def run(args: argparse.Namespace) -> int:
    from analysis.stability.output import lobes_file

    out, line = lobes_file(args.config, args.output, args.method, args.steps, args.max_depth,
                           args.plot, note=noter("analyze stability"))  # fmt: skip
    return show(args.json, out, lambda: [line])

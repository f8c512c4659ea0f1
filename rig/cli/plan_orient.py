"""`cutlab plan orient CONFIG -o OUT [--json]`: collision-free 5-axis tool orientation (seed 002).

Writes to the folder OUT: ``cl.csv`` (CL data: tip, cutter centre, axis, angles per CC point),
``program.nc`` (G-code for the config's 5-axis machine by inverse kinematics),
``energy_map.png`` (the eq 7 energy over (alpha, beta) at one CC point, as seed 002 Fig. 8),
``orientation.png`` (the surfaces with the chosen tool axes, as Figs. 9-11) and
``summary.json``. Every output orientation is re-checked on a fresh dense mesh before anything
is written; a CC point without a collision-free orientation stops the command with its reason.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rig.cli.common import count, print_json, print_table, status
from rig.cli.options import REQUIRED, command, dialect_row
from rig.terminal import Progress


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``orient`` to the ``plan`` group."""
    command(sub, "orient", "collision-free 5-axis tool orientation (potential energy, seed 002)", [
        ("config", Path, None, "orientation config, e.g. configs/orient/impeller.toml"),
        ("-o --out", Path, REQUIRED, "output folder"),
        ("--json", bool, None, "print the summary as JSON"),
        ("--map-point", count(0), None, "CC point for the energy map (default: the one that "
         "needed most energy evaluations)"),
        ("--no-plot", bool, None, "skip both PNGs (energy map and orientation)"),
        dialect_row("controller to write for (default: the machine's); grbl has no rotary axes "
                    "and is refused"),
    ], run, catalogs=True, description=__doc__,
       formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip


def _show(v):
    """Ranges as "lo .. hi" with 4 significant digits, not raw float lists."""
    return f"{v[0]:.4g} .. {v[1]:.4g}" if isinstance(v, list) and len(v) == 2 else v


def run(args: argparse.Namespace) -> int:
    from planning.orient import run_orient

    with Progress("orient", "pt") as bar:

        def note(msg: str) -> None:  # the points are planned: the bar gives way to the line
            bar.close()
            status(msg)

        summary = run_orient(
            args.config, args.out, args.map_point, not args.no_plot, bar, note, args.dialect
        )
    if args.json:
        print_json(summary)
        return 0
    print_table([{"quantity": k, "value": _show(v)} for k, v in summary.items() if k != "files"])
    for f in summary["files"]:
        print(f)
    return 0

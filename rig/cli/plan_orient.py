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

from rig.cli.common import bar_note, count, show
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


def run(args: argparse.Namespace) -> int:
    from planning.orient import run_orient, summary_lines

    with Progress("orient", "pt") as bar:  # the points planned, the bar gives way to the notes
        summary = run_orient(args.config, args.out, args.map_point, not args.no_plot, bar,
                             bar_note(bar), args.dialect)  # fmt: skip
    return show(args.json, summary, lambda: summary_lines(summary))

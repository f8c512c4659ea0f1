"""`cutlab demo` — interim: runs the NC pipeline on a shipped sample program.

Until the simulated rig lands this parses and interprets ``data/programs/demo-part.nc`` on the
``ace-h63`` machine, prints the program's statistics, plots the tool path to a PNG and says what it
did. (The simulated-rig work replaces this with a full campaign.)
"""

from __future__ import annotations

import argparse
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SAMPLE = REPO / "data" / "programs" / "demo-part.nc"


def _demo(args: argparse.Namespace) -> int:
    from analysis.config import load_machine
    from planning.nc import Interpreter, Program, motion_stats
    from planning.nc.plot import plot_motion
    from rig.cli._common import print_json, print_table, status

    machine = load_machine(args.machine)
    program = Program.read(args.program)
    status(f"demo: read {args.program} ({len(program)} blocks)")
    it = Interpreter(machine, file=str(args.program))
    motion = it.run(program.lines)
    stats = motion_stats(motion, machine)
    out = Path(args.out)
    png = plot_motion(
        motion, out / "demo-toolpath.png", title=f"{Path(args.program).name} on {machine.name}"
    )
    status(f"demo: interpreted {len(motion)} motion segments; wrote tool path plot {png}")
    summary = {
        "program": str(args.program),
        "machine": machine.name,
        "blocks": len(program),
        "motions": len(motion),
        "cutting_length_mm": stats.cutting_length_mm,
        "rapid_length_mm": stats.rapid_length_mm,
        "time_s": stats.time_s,
        "plot": str(png),
    }
    if args.json:
        print_json(summary)
    else:
        print_table([{"quantity": k, "value": v} for k, v in summary.items()])
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    p = sub.add_parser("demo", help="run the main job (interim: the NC pipeline on a sample part)")
    p.add_argument("--program", default=str(SAMPLE), help="NC program (default: the sample part)")
    p.add_argument("--machine", default="ace-h63", help="machine config name or path")
    p.add_argument("--out", default="out/demo", help="folder for the PNG (created)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=_demo)

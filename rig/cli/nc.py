"""`cutlab nc` — check, list and plot NC programs (planning.nc).

``check`` prints the errors (exit 2, one line) or the program's lengths, time, bbox and warnings;
with ``--dialect`` also what that controller would refuse (``--json``: ``dialect_problems``; exit
2 if it would refuse a line). ``motions``: one row per canonical segment; ``plot``: the tool path.

``--dialect NAME`` on all three interprets the program as that controller does (LinuxCNC: G10
L20, F in the units of a G20/G21 in the same block, its arc tolerance, its order of execution;
no machine file needed) unless ``--machine`` names a machine, whose own dialect then interprets
(``--dialect`` beside it only lists what the other control would refuse).
"""

from __future__ import annotations

import argparse
import sys

from rig.cli.common import image_file, print_json, print_table, status
from rig.cli.options import REQUIRED, command, dialect_row, group, json_row
from rig.terminal import Progress


def _interpret(args: argparse.Namespace, *, warn: bool = True, keep_motion: bool = False):
    """``args.file`` interpreted; its warnings go to stderr unless ``warn`` is False."""
    from planning.nc import check_program

    with Progress("interpreting", "B", unit_scale=True) as bar:
        run = check_program(args.file, args.machine, strict=not args.lenient, progress=bar,
                            keep_motion=keep_motion, dialect=args.dialect)  # fmt: skip
    for w in run.warnings if warn else ():
        status(f"warning: {w}")
    return run


def _check(args: argparse.Namespace) -> int:
    from planning.nc import NCError
    from planning.nc.check_text import refused_summary, summary_rows

    problems = None
    if args.dialect:
        from planning.nc.check import dialect_problems

        problems = dialect_problems(args.file, args.dialect)
        if not args.json:
            for p in problems:
                status(f"{p.severity}: {p}")
    refused = sum(p.severity == "error" for p in problems or ())
    try:
        run = _interpret(args, warn=not args.json)
    except NCError as exc:
        if not refused:
            raise
        # the controller refuses a line, so its reading of the program stops there: the
        # refusals are the answer (in --json as well), and the summary is not made
        if args.json:
            print_json(refused_summary(args.file, args.dialect, problems or (), str(exc)))
        else:
            status(f"{args.file}: {args.dialect} would refuse {refused} line(s)")
        return 2
    out = run.summary()
    if problems is not None:
        out["dialect"] = args.dialect
        out["dialect_problems"] = [p.as_dict() for p in problems]
    if args.json:
        print_json(out)
        return 2 if refused else 0
    if refused:
        status(f"{args.file}: {args.dialect} would refuse {refused} line(s)")
    for p in out["warnings"][len(run.warnings) :]:  # the machine's travel limits
        status("warning: " + p)
    print_table(summary_rows(out))
    return 2 if refused else 0


def _motions(args: argparse.Namespace) -> int:
    if args.csv or args.output:
        from planning.nc.check import write_motions_csv

        with Progress("interpreting", "B", unit_scale=True) as bar:
            it = write_motions_csv(args.file, args.output or sys.stdout, args.machine,
                                   strict=not args.lenient, progress=bar,
                                   dialect=args.dialect)  # fmt: skip
        for w in it.warnings:
            status(f"warning: {w}")
        return 0
    rows = _interpret(args, keep_motion=True).motion_table().to_dict(orient="records")
    print_json(rows) if args.json else print_table(rows)
    return 0


def _plot(args: argparse.Namespace) -> int:
    from planning.nc.plot import plot_motion

    motion = _interpret(args, keep_motion=True).motion
    path = plot_motion(motion, args.output, title=args.file)
    if args.json:
        print_json({"file": args.file, "plot": str(path), "motions": len(motion)})
    else:
        status(f"wrote {path} ({len(motion)} segments)")
    return 0


#: each command's first options: the program, its machine, how strict
# fmt: off
PROGRAM = [
    ("file", None, None, "NC program (RS-274 / Fanuc style)"),
    ("--machine", None, None, "machine config name or path (rapid rate, arc tolerance, dialect)"),
    ("--lenient", bool, None, "report unknown codes as warnings instead of errors"),
]
DIALECT = "interpret as this controller does (default: the machine's, else fanuc)"


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    nsub = group(sub, "nc", "check, list and plot NC programs")
    command(nsub, "check", "parse + interpret; print lengths, time, bbox (or the error)", [
        PROGRAM, json_row("machine-readable output"),
        dialect_row(DIALECT + " and list what it would refuse (exit 2 if any)"),
    ], _check)
    command(nsub, "motions", "one row per canonical motion segment", [
        PROGRAM, dialect_row(DIALECT), ("--csv", bool, None, "CSV to stdout (or to -o)"),
        ("-o --output", None, None, "write CSV to this file"), json_row("JSON records"),
    ], _motions)
    command(nsub, "plot", "PNG of the tool path (3-D and top views)", [
        PROGRAM, dialect_row(DIALECT), ("-o --output", image_file, REQUIRED, "PNG path"),
        json_row("machine-readable output"),
    ], _plot)
# fmt: on

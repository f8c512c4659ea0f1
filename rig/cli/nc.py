"""`cutlab nc` — check, list and plot NC programs (:mod:`planning.nc.check`: ``--dialect``
interprets as that controller does unless ``--machine`` names a machine, whose own dialect then
interprets; ``nc check --dialect`` also lists what that controller would refuse, exit 2)."""

from __future__ import annotations

import argparse
import sys

from analysis.output import table_lines
from rig.cli.common import image_file, show, status
from rig.cli.options import REQUIRED, command, dialect_row, group, json_row
from rig.terminal import Progress


def _interpret(args: argparse.Namespace):
    """``args.file`` interpreted, its motion kept; its warnings go to stderr."""
    from planning.nc import check_program

    with Progress("interpreting", "B", unit_scale=True) as bar:
        run = check_program(args.file, args.machine, strict=not args.lenient, progress=bar,
                            keep_motion=True, dialect=args.dialect)  # fmt: skip
    for w in run.warnings:
        status(f"warning: {w}")
    return run


def _check(args: argparse.Namespace) -> int:
    from planning.nc.check_text import check_answer

    with Progress("interpreting", "B", unit_scale=True) as bar:
        answer = check_answer(args.file, args.machine, args.dialect, strict=not args.lenient,
                              progress=bar, note=(lambda m: None) if args.json else status)
    return show(args.json, answer.summary, answer.lines, answer.code)


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
    rows = _interpret(args).motion_table().to_dict(orient="records")
    return show(args.json, rows, lambda: table_lines(rows))


def _plot(args: argparse.Namespace) -> int:
    from planning.nc.plot import plot_motion

    motion = _interpret(args).motion
    path = plot_motion(motion, args.output, title=args.file)
    return show(args.json, {"file": args.file, "plot": str(path), "motions": len(motion)},
                after=[f"wrote {path} ({len(motion)} segments)"])  # fmt: skip


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

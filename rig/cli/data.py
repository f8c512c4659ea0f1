"""`cutlab data` commands: look at run files and exports (:mod:`analysis.runs`); import exports
as run files (:mod:`rig.log`)."""

from __future__ import annotations

import argparse

from analysis.output import table_lines
from rig.cli.common import image_file, nonnegative, show, status
from rig.cli.options import REQUIRED, command, group, import_options, import_rows  # isort: split

from rig.cli.options import json_row, rate_row, rig_row
from rig.terminal import Progress


def _info(args: argparse.Namespace) -> int:
    from analysis.runs import file_info_lines, file_summary

    s = file_summary(args.file, args.rate)
    return show(args.json, s, lambda: file_info_lines(args.file, s))


def _plot(args: argparse.Namespace) -> int:
    from analysis.runs import plot_file

    png, samples = plot_file(args.file, args.output, args.rate, args.start_s, args.stop_s)
    status(f"data plot: wrote {png}")
    return show(args.json, {"file": args.file, "plot": str(png), "samples": samples},
                lambda: [str(png)])  # fmt: skip


def _import(args: argparse.Namespace) -> int:
    from analysis.identify.conditions_arg import conditions_arg
    from rig.log import import_exports

    pairs, table = conditions_arg(args.conditions)
    opts = import_options(args, table)
    if opts.auto:  # the mapping from an end-mill fit of all the exports, before any is written
        from dataclasses import replace

        from analysis.identify.files import auto_axes

        axes, line = auto_axes(args.files, pairs, args.rig, args.rate, args.tool, opts)
        status(f"data import: axes {line}")
        opts = replace(opts, axes=axes)
    with Progress("importing", "file", quiet=args.json or len(args.files) < 2) as bar:
        written = import_exports(args.files, args.output, pairs, opts, rig_path=args.rig,
                                 rate_hz=args.rate, tool=args.tool, overwrite=args.force,
                                 progress=bar)  # fmt: skip
    for w in written:
        status(f"data import: {w['source']} -> {w['file']}: axes {w['axes']}; offset: {w['zero']}")
    rows = [{"run file": w["file"], "samples": w["samples"], "rate_hz": w["rate_hz"],
             "axes": w["axes"], "offset": w["zero"]} for w in written]  # fmt: skip
    return show(args.json, {"written": written}, lambda: table_lines(rows))


FILE = ("file", None, None, "run file (.h5) or DynoWare/CSV export")


# fmt: off
def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    psub = group(sub, "data", "inspect and plot run files and exports; import exports")
    command(psub, "info", "what a run file or a DynoWare/CSV export holds",
            [FILE, rate_row(), json_row()], _info)
    command(psub, "plot", "force traces of a run file or an export as a PNG", [
        FILE, ("-o --output", image_file, "forces.png", "PNG to write"),
        ("--start-s", nonnegative("s"), None, "s after the first sample"),
        ("--stop-s", nonnegative("s"), None, "s after the first sample"),
        rate_row(), json_row(),
    ], _plot)
    command(psub, "import", "DynoWare/CSV exports into run files (.h5)", [
        ("files", None, None, "DynoWare/CSV exports", {"nargs": "+"}),
        ("-o --output", None, REQUIRED, "folder for the runs", {"metavar": "DIR"}),
        ("--conditions", None, None, "a conditions table (.csv/.toml, one row per file: file,"
         "spindle_rpm,feed_mm_min|fz_mm,ap_mm,ae_mm[,teeth,tool,mode]) or KEY=VALUE pairs for "
         "every file", {"nargs": "*", "metavar": "KEY=VALUE|TABLE"}),
        ("--tool", None, None, "tool name (configs/tools.toml or --tools)"),
        rate_row(), rig_row(), import_rows(), ("--force", bool, None, "replace existing run files"),
        json_row(),
    ], _import)
# fmt: on

"""`cutlab data` commands: look at run files and exports; import exports as run files.

``info``: a run file's channels, rate, duration, samples, events, gaps and status, or an
export's columns, units, rate, samples and header. ``import``: DynoWare / CSV exports into
ordinary run files (DIR/<name>.h5), conditions and all, so every command that reads run files
reads them.
"""

from __future__ import annotations

import argparse

from rig.cli.common import image_file, nonnegative, print_json, print_lines, print_table, status
from rig.cli.options import import_group, import_options, json_option, rate_option, rig_option
from rig.terminal import Progress


def _info(args: argparse.Namespace) -> int:
    from analysis.runs import file_info_lines, file_summary

    s = file_summary(args.file, args.rate)
    print_json(s) if args.json else print_lines(file_info_lines(args.file, s))
    return 0


def _plot(args: argparse.Namespace) -> int:
    from analysis.runs import plot_file

    png, samples = plot_file(args.file, args.output, args.rate, args.start_s, args.stop_s)
    status(f"data plot: wrote {png}")
    out = {"file": args.file, "plot": str(png), "samples": samples}
    print_json(out) if args.json else print(png)
    return 0


def _import(args: argparse.Namespace) -> int:
    from rig.log import import_exports

    pairs, opts = import_options(args)
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
    if args.json:
        print_json({"written": written})
        return 0
    print_table([{"run file": w["file"], "samples": w["samples"], "rate_hz": w["rate_hz"],
                  "axes": w["axes"], "offset": w["zero"]} for w in written])  # fmt: skip
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    p = sub.add_parser("data", help="inspect and plot run files and exports; import exports")
    psub = p.add_subparsers(dest="data_command", metavar="DATA_COMMAND")
    psub.required = True
    i = psub.add_parser("info", help="what a run file or a DynoWare/CSV export holds")
    i.add_argument("file", help="run file (.h5) or DynoWare/CSV export")
    rate_option(i)
    json_option(i)
    i.set_defaults(func=_info)
    g = psub.add_parser("plot", help="force traces of a run file or an export as a PNG")
    g.add_argument("file", help="run file (.h5) or DynoWare/CSV export")
    g.add_argument("-o", "--output", type=image_file, default="forces.png", help="PNG to write")
    g.add_argument("--start-s", type=nonnegative("s"), default=None,
                   help="s after the first sample")  # fmt: skip
    g.add_argument("--stop-s", type=nonnegative("s"), default=None,
                   help="s after the first sample")  # fmt: skip
    rate_option(g)
    json_option(g)
    g.set_defaults(func=_plot)
    m = psub.add_parser("import", help="DynoWare/CSV exports into run files (.h5)")
    m.add_argument("files", nargs="+", help="DynoWare/CSV exports")
    m.add_argument("-o", "--output", required=True, metavar="DIR", help="folder for the runs")
    m.add_argument(
        "--conditions", nargs="*", metavar="KEY=VALUE|TABLE",
        help="a conditions table (.csv/.toml, one row per file: file,spindle_rpm,"
        "feed_mm_min|fz_mm,ap_mm,ae_mm[,teeth,tool,mode]) or KEY=VALUE pairs for every file",
    )  # fmt: skip
    m.add_argument("--tool", default=None, help="tool name (configs/tools.toml or --tools)")
    rate_option(m)
    rig_option(m)
    import_group(m)
    m.add_argument("--force", action="store_true", help="replace existing run files")
    json_option(m)
    m.set_defaults(func=_import)

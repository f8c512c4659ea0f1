"""`cutlab data` commands: look at recorded HDF5 run files.

cutlab data info run.h5 [--json]     channels, rate, duration, samples, events, gaps, status
cutlab data plot run.h5 -o forces.png
"""

from __future__ import annotations

import argparse


def _info(args: argparse.Namespace) -> int:
    from analysis.runs import run_summary
    from rig.cli._common import print_json, print_table

    s = run_summary(args.file)
    if args.json:
        print_json(s)
        return 0
    if not s["complete"]:
        print(
            f"INCOMPLETE: the writer never closed {s['file']} (killed or still running); it holds "
            f"{s['samples_stored']} samples per channel = {s['duration_s']:.3f} s up to its last "
            "flush"
        )
    keys = ("status reason sample_format rate_hz samples_stored samples_acquired samples_lost "
            "duration_s nc_blocks calibration_id software_version").split()  # fmt: skip
    rows = [{"quantity": k, "value": s[k]} for k in keys]
    rows.insert(1, {"quantity": "channels", "value": " ".join(s["channels"])})
    rows.append(
        {"quantity": "events", "value": ", ".join(f"{k} {v}" for k, v in s["events"].items())}
    )
    if s["conditions"]:
        rows.append({"quantity": "conditions", "value": s["conditions"]})
    print_table(rows)
    if s["gaps"]:
        print()
        print_table(s["gaps"])
    return 0


def _plot(args: argparse.Namespace) -> int:
    from analysis.runs import load_run, plot_run
    from rig.cli._common import print_json, status

    run = load_run(args.file, args.start_s, args.stop_s)
    png = plot_run(run, args.output)
    status(f"data plot: wrote {png}")
    if args.json:
        print_json({"file": args.file, "plot": str(png), "samples": len(run.time_s)})
    else:
        print(png)
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    p = sub.add_parser("data", help="inspect and plot recorded run files")
    psub = p.add_subparsers(dest="data_command", metavar="DATA_COMMAND")
    psub.required = True
    i = psub.add_parser("info", help="channels, rate, duration, samples, events and gaps of a run")
    i.add_argument("file", help="run file (.h5)")
    i.add_argument("--json", action="store_true", help="JSON on stdout")
    i.set_defaults(func=_info)
    g = psub.add_parser("plot", help="force traces of a run as a PNG")
    g.add_argument("file", help="run file (.h5)")
    g.add_argument("-o", "--output", default="forces.png", help="PNG to write")
    g.add_argument("--start-s", type=float, default=None, help="s after the first sample")
    g.add_argument("--stop-s", type=float, default=None, help="s after the first sample")
    g.add_argument("--json", action="store_true", help="JSON on stdout")
    g.set_defaults(func=_plot)

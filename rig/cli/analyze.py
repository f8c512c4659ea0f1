"""`cutlab analyze` commands: force coefficients from runs (``forces``), modes from a hammer test
(``modal``), stability lobes (``stability``, :mod:`rig.cli.stability`); `--help` gives each one's
options.

RUN is an HDF5 run file (conditions from the file) or a DynoWare/plain CSV export (conditions
from its header lines), then a conditions table's row and the file-name pattern;
--conditions KEY=VALUE overrides them key by key for every run. A run that records
another tool than --tool is refused. With --catalog the runs are those of a run catalogue
(`cutlab catalog`) matching --where, each reduced as a dask task (local threads, or the
dask.distributed scheduler at --scheduler) and cached by file hash. A fit that the runs
cannot support prints its reason and exits with status 1; bad input exits with status 2.
"""

from __future__ import annotations

import argparse

from rig.cli.common import count, image_file, number, positive  # isort: split

from rig.cli.common import print_json, print_lines, print_table, status
from rig.cli.options import import_group, import_options, json_option, rate_option, rig_option
from rig.terminal import Progress


def _forces(args: argparse.Namespace) -> int:
    from analysis.identify import fit_files
    from analysis.identify.conditions_arg import runs_or_catalog
    from analysis.identify.text import forces_lines

    pairs, opts = import_options(args)
    kw = dict(model=args.model, tool=args.tool, overrides=pairs, rig_path=args.rig,
              rate_hz=args.rate, tolerance=args.steady_tolerance, validate=args.validate,
              plot_dir=args.plot, options=opts, keep=args.keep)  # fmt: skip
    if runs_or_catalog(args.runs, args.catalog, where=args.where, scheduler=args.scheduler):
        from analysis.catalog import fit_catalog

        out = fit_catalog(args.catalog, args.where, args.scheduler, not args.json, **kw)
        c = out["catalog"]
        how = ("the fit from the cache" if c["fit_cached"] else
               f"{c['cached']} from the cache, {c['reduced']} reduced")  # fmt: skip
        status(f"analyze forces: {c['runs']} run(s) from {c['index']}: {how}")
    else:
        with Progress("reducing runs", "run", quiet=args.json or len(args.runs) < 2) as bar:
            out = fit_files(args.runs, progress=bar, **kw)
    if "plots" in out:
        status(f"analyze forces: wrote {', '.join(out['plots'])}")
    for w in out["warnings"]:
        status(f"analyze forces: warning: {w}")
    print_json(out) if args.json else print_lines(forces_lines(out))
    return 0 if out["success"] else 1


def _modal(args: argparse.Namespace) -> int:
    from analysis.modal import modal_file

    out = modal_file(
        args.file, args.hammer, rate_hz=args.rate, record_s=args.record_s,
        window_end=args.window_end, spindle_rpm=args.rpm, teeth=args.teeth, rig_path=args.rig,
        plot_png=args.plot, response=args.response, stabilisation_png=args.stabilisation,
        save=args.save, columns=args.columns,
    )  # fmt: skip
    for key in ("plot", "stabilisation_plot", "saved"):
        if key in out:
            status(f"analyze modal: wrote {out[key]}")
    for w in out["warnings"]:
        status(f"analyze modal: warning: {w}")
    if args.json:
        print_json(out)
    else:
        print_table(out["modes"])
        for s in out["skipped"]:
            print(f"skipped {s['channel']}: {s['reason']}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    p = sub.add_parser("analyze", help="force coefficients from runs, dynamometer modes")
    psub = p.add_subparsers(dest="analyze_command", metavar="ANALYZE_COMMAND")
    psub.required = True
    _register_forces(psub)
    _register_modal(psub)
    from rig.cli.stability import register_stability

    register_stability(psub)


def _register_forces(psub: argparse._SubParsersAction) -> None:
    from analysis.runs import IDENTIFY_TOLERANCE

    f = psub.add_parser("forces", help="fit cutting-force coefficients to recorded runs")
    f.add_argument("runs", nargs="*", help="run files (.h5) or DynoWare/CSV exports")
    f.add_argument("--catalog", default=None, metavar="DIR|INDEX",
                   help="the runs of this run catalogue (`cutlab catalog index`) instead of "
                   "files, reduced as dask tasks and cached by file hash")  # fmt: skip
    f.add_argument("--where", default=None, metavar="EXPR",
                   help="with --catalog: the runs to fit, as `cutlab catalog query` takes them "
                   "(default every run)")  # fmt: skip
    f.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="with --catalog: a dask.distributed scheduler (tcp://HOST:PORT), or "
                   "threads / processes / sync (default: the dask config's scheduler-address, "
                   "else threads)")  # fmt: skip
    f.add_argument("--model", choices=("facemill", "endmill"), default=None,
                   help="force model (default: from the tool's kind)")  # fmt: skip
    f.add_argument("--tool", default=None, help="tool name in configs/tools.toml")
    rig_option(f)
    f.add_argument(
        "--conditions", nargs="*", metavar="KEY=VALUE|TABLE",
        help="conditions applied over each run's own (file header or run file), key by key "
        "(spindle_rpm=600 depth_mm=2 mode=slot ...), or a table (.csv/.toml, one row per file: "
        "file,spindle_rpm,feed_mm_min|fz_mm,ap_mm,ae_mm[,teeth,tool,mode])",
    )  # fmt: skip
    rate_option(f)
    import_group(f)
    f.add_argument(
        "--steady-tolerance", type=number("fraction", 0, 1, lo_open=True),
        default=IDENTIFY_TOLERANCE, metavar="FRACTION",
        help="revolutions whose mean force is within this fraction of the steady level (median) "
        f"count as steady cutting; fraction, default {IDENTIFY_TOLERANCE} (0.02 = 2 %%)",
    )  # fmt: skip
    f.add_argument("--validate", nargs="*", default=None, metavar="RUN",
                   help="runs to predict with the fitted coefficients")  # fmt: skip
    f.add_argument("--plot", default=None, metavar="DIR", help="write validation PNGs here")
    f.add_argument("--keep", action="store_true",
                   help="fit runs beyond the tool's limits too (max_chip_mm): by default they "
                   "are named and left out")  # fmt: skip
    json_option(f)
    f.set_defaults(func=_forces)


def _register_modal(psub: argparse._SubParsersAction) -> None:
    m = psub.add_parser("modal", help="modes from an impulse-hammer record (dynamometer, tool)")
    m.add_argument("file", help="CSV/DynoWare export or run file with a hammer channel")
    m.add_argument("--hammer", default="hammer", help="name of the hammer force channel")
    m.add_argument(
        "--columns", default=None, metavar="NAMES",
        help="the columns of a file without a header row, in order, units in brackets: "
        "e.g. time[s],hammer[N],accel[m/s^2] (the rate from the time column, or --rate)",
    )  # fmt: skip
    rate_option(m, "files")
    m.add_argument("--record-s", type=positive("s", 3600), default=0.08,
                   help="s of record per hit (at least 0.01 s and 128 samples)")  # fmt: skip
    m.add_argument("--window-end", type=number("", 0, 1, lo_open=True), default=0.05,
                   help="exponential window value at the record's end")  # fmt: skip
    m.add_argument(
        "--response", choices=("force", "disp", "accel"), default=None,
        help="what response columns without a unit in their name measure: force (N, a "
        "dynamometer; the default), disp (m) or accel (m/s^2); a unit in the column name "
        "(ax [g], dx [mm]) decides by itself",
    )  # fmt: skip
    m.add_argument("--rpm", type=positive("rpm", 1_000_000), nargs="*", default=None,
                   help="planned spindle speeds to check against the modes")  # fmt: skip
    m.add_argument("--teeth", type=count(1, 1000), default=1, help="teeth of the planned cutter")
    rig_option(m)
    m.add_argument("--plot", type=image_file, default=None, metavar="PNG",
                   help="write the FRF and coherence")  # fmt: skip
    m.add_argument("--stabilisation", type=image_file, default=None, metavar="PNG",
                   help="write the stabilisation diagram (LSCF poles by model order)")  # fmt: skip
    m.add_argument(
        "--save", default=None, metavar="MODES.toml",
        help="write the modes per direction (frequency, damping, modal stiffness and mass) for "
        "a stability calculation; .toml or .json",
    )  # fmt: skip
    json_option(m)
    m.set_defaults(func=_modal)

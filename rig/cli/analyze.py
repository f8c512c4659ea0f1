"""`cutlab analyze` commands: force coefficients from runs (``forces``: how runs are read,
:mod:`analysis.identify.reading`; a catalogue's runs, :mod:`analysis.catalog`), modes from a
hammer test (``modal``), stability lobes (``stability``, :mod:`rig.cli.stability`). A fit that
the runs cannot support prints its reason and exits with status 1; bad input exits with status 2.
"""

from __future__ import annotations

import argparse

from analysis.runs import IDENTIFY_TOLERANCE
from rig.cli.common import count, image_file, number, positive, print_notes, show, status
from rig.cli.options import command, group, import_options, import_rows, json_row, rate_row, rig_row
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
        from analysis.catalog import fit_catalog, fit_line

        out = fit_catalog(args.catalog, args.where, args.scheduler, not args.json, **kw)
        status(f"analyze forces: {fit_line(out)}")
    else:
        with Progress("reducing runs", "run", quiet=args.json or len(args.runs) < 2) as bar:
            out = fit_files(args.runs, progress=bar, **kw)
    print_notes("analyze forces", out, wrote=("plots",))
    return show(args.json, out, lambda: forces_lines(out), 0 if out["success"] else 1)


def _modal(args: argparse.Namespace) -> int:
    from analysis.modal import modal_file, modal_lines

    out = modal_file(
        args.file, args.hammer, rate_hz=args.rate, record_s=args.record_s,
        window_end=args.window_end, spindle_rpm=args.rpm, teeth=args.teeth, rig_path=args.rig,
        plot_png=args.plot, response=args.response, stabilisation_png=args.stabilisation,
        save=args.save, columns=args.columns,
    )  # fmt: skip
    print_notes("analyze modal", out, wrote=("plot", "stabilisation_plot", "saved"))
    return show(args.json, out, lambda: modal_lines(out))


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    from rig.cli.stability import register_stability

    psub = group(sub, "analyze", "force coefficients from runs, dynamometer modes")
    command(psub, "forces", "fit cutting-force coefficients to recorded runs", FORCES, _forces)
    command(psub, "modal", "modes from an impulse-hammer record (dynamometer, tool)", MODAL, _modal)
    register_stability(psub)


# fmt: off
FORCES = (
    ("runs", None, None, "run files (.h5) or DynoWare/CSV exports", {"nargs": "*"}),
    ("--catalog", None, None, "the runs of this run catalogue (`cutlab catalog index`) instead "
     "of files, reduced as dask tasks and cached by file hash", {"metavar": "DIR|INDEX"}),
    ("--where", None, None, "with --catalog: the runs to fit, as `cutlab catalog query` takes "
     "them (default every run)", {"metavar": "EXPR"}),
    ("--scheduler", None, None, "with --catalog: a dask.distributed scheduler (tcp://HOST:PORT), "
     "or threads / processes / sync (default: the dask config's scheduler-address, else "
     "threads)", {"metavar": "ADDRESS"}),
    ("--model", ("facemill", "endmill"), None, "force model (default: from the tool's kind)"),
    ("--tool", None, None, "tool name in configs/tools.toml"),
    rig_row(),
    ("--conditions", None, None, "conditions applied over each run's own (file header or run "
     "file), key by key (spindle_rpm=600 depth_mm=2 mode=slot ...), or a table (.csv/.toml, one "
     "row per file: file,spindle_rpm,feed_mm_min|fz_mm,ap_mm,ae_mm[,teeth,tool,mode])",
     {"nargs": "*", "metavar": "KEY=VALUE|TABLE"}),
    rate_row(),
    import_rows(),
    ("--steady-tolerance", number("fraction", 0, 1, lo_open=True), IDENTIFY_TOLERANCE,
     "revolutions whose mean force is within this fraction of the steady level (median) count "
     f"as steady cutting; fraction, default {IDENTIFY_TOLERANCE} (0.02 = 2 %%)",
     {"metavar": "FRACTION"}),
    ("--validate", None, None, "runs to predict with the fitted coefficients",
     {"nargs": "*", "metavar": "RUN"}),
    ("--plot", None, None, "write validation PNGs here", {"metavar": "DIR"}),
    ("--keep", bool, None, "fit runs beyond the tool's limits too (max_chip_mm): by default they "
     "are named and left out"),
    json_row(),
)
MODAL = (
    ("file", None, None, "CSV/DynoWare export or run file with a hammer channel"),
    ("--hammer", None, "hammer", "name of the hammer force channel"),
    ("--columns", None, None, "the columns of a file without a header row, in order, units in "
     "brackets: e.g. time[s],hammer[N],accel[m/s^2] (the rate from the time column, or --rate)",
     {"metavar": "NAMES"}),
    rate_row("files"),
    ("--record-s", positive("s", 3600), 0.08, "s of record per hit (at least 0.01 s and 128 "
     "samples)"),
    ("--window-end", number("", 0, 1, lo_open=True), 0.05, "exponential window value at the "
     "record's end"),
    ("--response", ("force", "disp", "accel"), None, "what response columns without a unit in "
     "their name measure: force (N, a dynamometer; the default), disp (m) or accel (m/s^2); a "
     "unit in the column name (ax [g], dx [mm]) decides by itself"),
    ("--rpm", positive("rpm", 1_000_000), None, "planned spindle speeds to check against the "
     "modes", {"nargs": "*"}),
    ("--teeth", count(1, 1000), 1, "teeth of the planned cutter"),
    rig_row(),
    ("--plot", image_file, None, "write the FRF and coherence", {"metavar": "PNG"}),
    ("--stabilisation", image_file, None, "write the stabilisation diagram (LSCF poles by model "
     "order)", {"metavar": "PNG"}),
    ("--save", None, None, "write the modes per direction (frequency, damping, modal stiffness "
     "and mass) for a stability calculation; .toml or .json", {"metavar": "MODES.toml"}),
    json_row(),
)
# fmt: on

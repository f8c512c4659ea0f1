"""`cutlab nc` — check, list and plot NC programs (planning.nc).

* ``cutlab nc check FILE [--json] [--machine NAME] [--lenient]``: errors (exit 2, one line), or
  blocks, motions, cutting_length_mm, rapid_length_mm, time_s, bbox and warnings.
* ``cutlab nc motions FILE [--csv] [-o OUT]``: one row per canonical segment (line, kind,
  x0 y0 z0 x1 y1 z1, arc centre, feed, ...).
* ``cutlab nc plot FILE -o path.png``: tool path, rapids dashed, feeds solid, 3-D and top views.
"""

from __future__ import annotations

import argparse
import sys


def _machine(name: str | None):
    if not name:
        return None
    from analysis.config import load_machine

    return load_machine(name)


def _progress_lines(path: str):
    """The file's lines, with a tqdm bar on stderr (by bytes) for big files."""
    import os

    from planning.nc.run import file_lines

    try:
        size = os.path.getsize(path)
    except OSError:
        size = 0
    if size < 2_000_000:
        yield from file_lines(path)
        return
    from tqdm import tqdm

    with tqdm(total=size, unit="B", unit_scale=True, desc="interpreting", disable=None) as bar:
        done = 0
        for i, raw in enumerate(file_lines(path)):
            done += len(raw)
            if i % 20_000 == 0:  # update rarely: the loop does ~200k lines/s
                bar.update(done - bar.n)
            yield raw
        bar.update(size - bar.n)


def _interpret(args: argparse.Namespace, *, warn: bool = True):
    """(interpreter, motion, machine) of ``args.file``; the warnings go to stderr unless
    ``warn`` is False (the caller reports them itself)."""
    from planning.nc import Interpreter

    machine = _machine(args.machine)
    it = Interpreter(machine, strict=not args.lenient, file=args.file)
    motion = it.run(_progress_lines(args.file))
    if warn:
        for w in it.warnings:
            print(f"warning: {w}", file=sys.stderr)
    return it, motion, machine


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", help="NC program (RS-274 / Fanuc style)")
    p.add_argument(
        "--machine",
        default=None,
        help="machine config name or path (rapid rate, arc tolerance, dialect)",
    )
    p.add_argument(
        "--lenient", action="store_true", help="report unknown codes as warnings instead of errors"
    )


def _check(args: argparse.Namespace) -> int:
    from planning.nc import motion_stats
    from planning.nc.stats import axis_limit_problems
    from rig.cli._common import print_json, print_table, status

    it, motion, machine = _interpret(args, warn=not args.json)
    st = motion_stats(motion, machine)
    limits = [f"{args.file}: {p}" for p in axis_limit_problems(motion, machine)]
    if not args.json:
        for p in limits:
            status("warning: " + p)
    out = {
        "file": args.file,
        "blocks": it.blocks_seen,
        "motions": len(motion),
        "cutting_length_mm": st.cutting_length_mm,
        "rapid_length_mm": st.rapid_length_mm,
        "time_s": st.time_s,
        "time_with_accel_s": st.accel_time_s,
        "feed_time_s": st.feed_time_s,
        "rapid_time_s": st.rapid_time_s,
        "dwell_s": st.dwell_s,
        "rapid_mm_min": st.rapid_mm_min,
        "bbox": {"min_mm": list(st.bbox_min_mm), "max_mm": list(st.bbox_max_mm)},
        "warnings": [str(w) for w in it.warnings] + limits,
    }
    rotary = motion.has_rotary_travel.any() or any(st.rotary_min_deg) or any(st.rotary_max_deg)
    if rotary:
        out["rotary_range_deg"] = {
            c: [st.rotary_min_deg[i], st.rotary_max_deg[i]] for i, c in enumerate("ABC")
        }
    if args.json:
        print_json(out)
        return 0
    skip = ("bbox", "warnings", "rotary_range_deg")
    rows = [{"quantity": k, "value": v} for k, v in out.items() if k not in skip and v is not None]
    for c, (lo, hi) in out.get("rotary_range_deg", {}).items():
        rows.append({"quantity": f"{c}_range_deg", "value": f"{lo:.4g} {hi:.4g}"})
    rows.append({"quantity": "bbox_min_mm", "value": " ".join(f"{c:.4g}" for c in st.bbox_min_mm)})
    rows.append({"quantity": "bbox_max_mm", "value": " ".join(f"{c:.4g}" for c in st.bbox_max_mm)})
    print_table(rows)
    return 0


def _motions(args: argparse.Namespace) -> int:
    from rig.cli._common import print_table

    _, motion, _ = _interpret(args)
    df = motion.to_dataframe()
    if not (motion.rotary_start_deg.any() or motion.rotary_end_deg.any()):
        df = df.drop(columns=["a0", "b0", "c0", "a1", "b1", "c1"])  # a 3-axis program
    if args.csv or args.output:
        if args.output:
            df.to_csv(args.output, index=False, float_format="%.6g")
        else:
            df.to_csv(sys.stdout, index=False, float_format="%.6g")
        return 0
    if args.json:
        from rig.cli._common import print_json

        print_json(df.to_dict(orient="records"))
        return 0
    print_table(df.to_dict(orient="records"))
    return 0


def _plot(args: argparse.Namespace) -> int:
    from planning.nc.plot import plot_motion
    from rig.cli._common import print_json, status

    _, motion, _ = _interpret(args)
    path = plot_motion(motion, args.output, title=args.file)
    if args.json:
        print_json({"file": args.file, "plot": str(path), "motions": len(motion)})
    else:
        status(f"wrote {path} ({len(motion)} segments)")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    nc = sub.add_parser("nc", help="check, list and plot NC programs")
    nsub = nc.add_subparsers(dest="nc_command", metavar="NC_COMMAND")
    nsub.required = True

    p = nsub.add_parser("check", help="parse + interpret; print lengths, time, bbox (or the error)")
    _add_common(p)
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=_check)

    p = nsub.add_parser("motions", help="one row per canonical motion segment")
    _add_common(p)
    p.add_argument("--csv", action="store_true", help="CSV to stdout (or to -o)")
    p.add_argument("-o", "--output", default=None, help="write CSV to this file")
    p.add_argument("--json", action="store_true", help="JSON records")
    p.set_defaults(func=_motions)

    p = nsub.add_parser("plot", help="PNG of the tool path (3-D and top views)")
    _add_common(p)
    p.add_argument("-o", "--output", required=True, help="PNG path")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=_plot)

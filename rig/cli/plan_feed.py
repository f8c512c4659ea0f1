"""`cutlab plan feed` and `cutlab plan simulate`: Z-map virtual machining and the load-based feed
post-processor (seed 001).

* ``cutlab plan feed IN.nc --rules RULE [--machine M] [--tool T] [--stock S] -o OUT.nc [--json]``
  computes each block's cutting load on a Z-map, picks feeds from the rule (a rule file, or a
  rule-base name / id), splits blocks where the load changes, clamps to the machine, and writes
  OUT.nc with only F words and splits changed, plus a report (CSV, PNGs) next to it.
* ``cutlab plan simulate IN.nc|PLAN.toml [--tool T] [--stock S] --png stock.png [--json]``:
  virtual machining alone (removed volume, time, holder contacts, final stock PNG). A plan file
  runs several programs, each with its tool, on the same stock.

Every input problem (missing tool, a rule with gaps, a program outside the stock or the machine's
travel, an arc the machine cannot cut) is reported before any file is written.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``feed`` and ``simulate`` to the ``plan`` group."""
    f = sub.add_parser("feed", help="adjust feeds by predicted cutting load (seed 001)")
    f.add_argument("program", type=Path, help="NC program (G21 or G20)")
    f.add_argument("--rules", required=True, help="rule file (TOML) or rule-base name / id")
    f.add_argument("--db", type=Path, help="rule base for a name / id (default from lab.toml)")
    _common(f)
    f.add_argument("-o", "--output", type=Path, required=True, help="adjusted program to write")
    f.add_argument("--report", type=Path, help="report folder (default: OUT's folder)")
    f.add_argument("--min-piece", type=float, default=5.0, help="shortest split block, mm")
    f.add_argument("--no-split", action="store_true", help="one feed per block, no splits")
    f.add_argument("--force-limit", type=float, help="largest predicted peak force, N")
    f.add_argument(
        "--material",
        help="material (configs/materials.toml): predicted peak force per block, and the "
        "coefficients for --force-limit",
    )
    f.add_argument("--spindle", type=float, help="rpm for the force model if the program has no S")
    f.set_defaults(func=_feed)

    s = sub.add_parser("simulate", help="Z-map virtual machining of a program or a plan")
    s.add_argument("program", type=Path, help="NC program, or an operation plan (.toml)")
    _common(s)
    s.add_argument("--png", type=Path, help="final stock PNG")
    s.set_defaults(func=_simulate)


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--machine", default="ace-h63", help="machine config name or path")
    p.add_argument(
        "--tool", help="end mill in configs/tools.toml (needed for a program; plans name theirs)"
    )
    p.add_argument(
        "--stock",
        help="box:XMIN,XMAX,YMIN,YMAX,BOTTOM,TOP | mesh (.stl) | stock TOML "
        "(default: a box over the feed moves, top at Z0)",
    )
    p.add_argument("--spacing", type=float, help="Z-map grid spacing, mm (default 0.25)")
    p.add_argument("--no-holder-check", action="store_true", help="skip holder/stock checks")
    p.add_argument("--json", action="store_true", help="machine-readable output on stdout")


def _tool(name: str | None):
    from analysis.config import EndMill, get_tool, load_tools
    from planning.errors import PlanningError

    if not name:
        known = ", ".join(sorted(k for k, t in load_tools().items() if isinstance(t, EndMill)))
        raise PlanningError(f"--tool is required (an end mill of configs/tools.toml): {known}")
    tool = get_tool(name)
    if not isinstance(tool, EndMill):
        raise PlanningError(f"tool '{name}' is a {tool.kind}: the Z-map models end mills only")
    return tool


def _rule(spec: str, db: Path | None):
    from analysis.rules import load_rule

    p = Path(spec)
    if p.exists() or p.suffix == ".toml":
        return load_rule(p)
    from analysis.rules import RuleBase

    with RuleBase(db, create=False) as base:
        return base.find(spec).rule


class _Progress:
    """A tqdm bar on stderr, created at the first report (nothing shows if checks fail first)."""

    def __init__(self, desc: str) -> None:
        self.desc = desc
        self.bar = None

    def __call__(self, done: int, total: int) -> None:
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(
                total=total, unit="piece", desc=self.desc, file=sys.stderr, leave=False,
                disable=None,  # no bar when stderr is not a terminal (CI logs)
            )  # fmt: skip
        self.bar.total = total
        self.bar.n = done
        self.bar.refresh()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _load(args: argparse.Namespace):
    from analysis.config import load_machine
    from planning.errors import PlanningError
    from planning.nc import Program, interpret
    from planning.stock import Cutter, default_stock, load_stock

    machine = load_machine(args.machine)
    tool = _tool(args.tool)
    program = Program.read(args.program)
    motion = interpret(program, machine, file=str(args.program), cutter_comp="refuse")
    cutter = Cutter.from_tool(tool)
    if args.stock:
        stock = load_stock(args.stock, args.spacing)
    else:
        try:
            stock = default_stock(motion, cutter, args.spacing)
        except PlanningError as exc:
            raise PlanningError(f"{args.program}: {exc}") from None
    return machine, tool, program, motion, stock


def _feed(args: argparse.Namespace) -> int:
    from analysis.config import get_material
    from planning.errors import PlanningError
    from planning.feed import FeedPostOptions, post_process, write_report
    from rig.cli._common import print_json, print_table, status

    rule = _rule(args.rules, args.db)
    machine, tool, program, motion, stock = _load(args)
    if rule.tool and rule.tool != args.tool:
        status(
            f"warning: rule '{rule.name}' was derived with tool '{rule.tool}', not "
            f"'{args.tool}': its loads (relative to that tool's size) do not carry over"
        )
    coef = None
    if args.force_limit is not None and not args.material:
        raise PlanningError("--force-limit needs --material (its [endmill] coefficients)")
    if args.material:
        coef = get_material(args.material).endmill
        if coef is None:
            raise PlanningError(f"material '{args.material}' has no [endmill] coefficients")
    opts = FeedPostOptions(
        min_piece_mm=args.min_piece,
        split=not args.no_split,
        check_holder=not args.no_holder_check,
        force_limit_n=args.force_limit,
        coefficients=coef,
        spindle_rpm=args.spindle,
    )
    bar = _Progress("simulate")
    try:
        result = post_process(program, motion, tool, rule, stock, machine, opts, progress=bar)
    finally:
        bar.close()
    args.output.parent.mkdir(parents=True, exist_ok=True)
    result.program.write(args.output)
    report = write_report(result, args.report or args.output.parent, args.output.stem)
    summary = result.summary()
    summary.update({"output": str(args.output), "report": {k: str(v) for k, v in report.items()}})
    if args.json:
        print_json(summary)
        return 0
    status(f"wrote {args.output} and report {report['csv'].parent}/{args.output.stem}-*")
    for c in result.simulation.contacts:
        status("warning: " + c.message(str(args.program)))
    for n in result.notes:
        status("note: " + n)
    print_table(
        [
            {"": "machining time (s)", "before": result.time_before_s,
             "after": result.time_after_s},
            {"": "with acceleration (s)", "before": result.accel_time_before_s,
             "after": result.accel_time_after_s},
            {"": "max load x feed", "before": summary["load_rate_max_before"],
             "after": summary["load_rate_max_after"]},
        ]
    )  # fmt: skip
    print(
        f"time saved {result.time_saved_pct:.1f} %, {result.split_blocks} blocks split, "
        f"removed {result.simulation.removed_total_mm3:.1f} mm^3"
    )
    return 0


def _simulate(args: argparse.Namespace) -> int:
    from planning.stock.machining import Operation, OperationPlan, load_plan, summary
    from rig.cli._common import print_json, print_table, status

    if args.program.suffix.lower() == ".toml":
        plan, _ = load_plan(args.program, args.spacing)
    else:
        machine, tool, _, motion, stock = _load(args)
        op = Operation(args.program.stem, motion, tool, args.tool, str(args.program))
        plan = OperationPlan(stock, [op], machine)
    start_volume = plan.stock.volume_mm3()
    bar = _Progress("simulate")
    try:
        results = plan.run(
            check_holder=not args.no_holder_check, progress=lambda name, d, t: bar(d, t)
        )
    finally:
        bar.close()
    rows = [summary(r) for r in results]
    if args.png:
        from planning.stock import save_stock_png

        save_stock_png(
            plan.stock, args.png, f"stock after {', '.join(r['operation'] for r in rows)}"
        )
    out = {
        "operations": rows,
        "stock_volume_before_mm3": start_volume,
        "stock_volume_after_mm3": plan.stock.volume_mm3(),
        "removed_mm3": sum(r["removed_mm3"] for r in rows),
        "time_s": sum(r["time_s"] for r in rows),
        "png": str(args.png) if args.png else None,
    }
    if args.json:
        print_json(out)
        return 0
    for r, res in zip(rows, results):
        for c in res.simulation.contacts:
            status("warning: " + c.message(r["file"]))
    print_table(
        [
            {k: r[k] for k in ("operation", "tool", "segments", "removed_mm3", "time_s")}
            | {"holder_contacts": len(r["holder_contacts"])}
            for r in rows
        ]
    )
    if args.png:
        status(f"wrote {args.png}")
    return 0

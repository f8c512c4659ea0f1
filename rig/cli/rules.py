"""`cutlab rules ...`: derive feed rules from feed sweeps and manage the rule base (seed 001)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from rig.cli._common import print_json, print_table, status


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("rules", help="feed rules: derive from feed sweeps, the rule base")
    rs = p.add_subparsers(dest="rules_command", metavar="RULES_COMMAND")
    rs.required = True

    d = rs.add_parser("derive", help="base feed from a feed sweep, then the 20-bin rule")
    d.add_argument("runs", nargs="+", type=Path, help="HDF5 run files of the feed sweep")
    d.add_argument("-o", "--output", type=Path, required=True, help="rule file to write (TOML)")
    d.add_argument("--name", help="rule name (default: the output file's stem)")
    d.add_argument("--base-feed", type=float, help="mm/min; skip the detection and use this")
    d.add_argument("--min-feed", type=float, help="mm/min (default: 0.1 x base, seed 001)")
    d.add_argument("--max-feed", type=float, help="mm/min (default: 3.5 x base, seed 001)")
    d.add_argument("--machine", help="machine config: min/max feeds are clamped to its limits")
    d.add_argument(
        "--reference-load",
        type=float,
        help="%%, load of the base-feed cut (default: a slot at the runs' depth)",
    )
    d.add_argument(
        "--exponent",
        type=float,
        default=1.0,
        help="p in feed = base (L_ref/L)^p (1: constant removal rate)",
    )
    d.add_argument("--bins", type=int, default=20)
    d.add_argument("--slope-ratio", type=float, default=1.6)
    d.add_argument("--vibration-ratio", type=float, default=2.0)
    d.add_argument("--criterion", choices=["any", "both", "slope", "vibration"], default="any")
    d.add_argument("--png", type=Path, help="also plot the rule and the sweep here")
    d.add_argument("--json", action="store_true")
    d.set_defaults(func=_derive)

    def key_args(q: argparse.ArgumentParser, required: bool = True) -> None:
        q.add_argument("--part-family", required=required, help="e.g. trunk/outer/draw/lower-die")
        q.add_argument(
            "--operation", required=required, help="roughing, pencil, rest-roughing, ..."
        )
        q.add_argument("--tool-diameter", type=float, required=required, help="mm")
        q.add_argument("--flute-length", type=float, required=required, help="mm")
        q.add_argument("--material", required=required)
        q.add_argument("--spindle", type=float, required=required, help="rpm")
        q.add_argument("--depth", type=float, required=required, help="mm")
        q.add_argument("--tolerance", type=float, required=required, help="mm")

    a = rs.add_parser("add", help="store a rule file in the rule base for a machining group")
    a.add_argument("rule", type=Path)
    key_args(a)
    a.add_argument("--note", default="")
    a.add_argument("--replace", action="store_true", help="replace the group's existing rule")
    a.add_argument("--db", type=Path, help="rule base (default from configs/lab.toml)")
    a.add_argument("--json", action="store_true")
    a.set_defaults(func=_add)

    ls = rs.add_parser("list", help="the machining groups in the rule base")
    ls.add_argument("--db", type=Path)
    ls.add_argument("--json", action="store_true")
    ls.set_defaults(func=_list)

    sh = rs.add_parser("show", help="one rule: its bins (by rule name, group id or rule file)")
    sh.add_argument("rule", help="rule name or group id in the rule base, or a rule file")
    sh.add_argument("--db", type=Path)
    sh.add_argument("--png", type=Path, help="plot load vs feed with the bins")
    sh.add_argument("--json", action="store_true")
    sh.set_defaults(func=_show)

    lk = rs.add_parser("lookup", help="the rule for a job: exact key or nearest match (stated)")
    key_args(lk)
    lk.add_argument("--exact", action="store_true", help="fail unless the key matches exactly")
    lk.add_argument("--db", type=Path)
    lk.add_argument("--json", action="store_true")
    lk.set_defaults(func=_lookup)

    ex = rs.add_parser("export", help="write a stored rule to a file, exactly as stored")
    ex.add_argument("rule", help="rule name or group id")
    ex.add_argument("-o", "--output", type=Path, required=True)
    ex.add_argument("--db", type=Path)
    ex.set_defaults(func=_export)


def _open(db: Path | None):
    """The rule base of ``--db`` (default from configs/lab.toml) for every command but ``add``:
    a path that does not exist is an error, not a new empty base (a typo must not read as one)."""
    from analysis.rules import RuleBase

    return RuleBase(db, create=False)


def _key(args: argparse.Namespace):
    from analysis.rules import GroupKey

    return GroupKey(
        args.part_family,
        args.operation,
        args.tool_diameter,
        args.flute_length,
        args.material,
        args.spindle,
        args.depth,
        args.tolerance,
    )


def _derive(args: argparse.Namespace) -> int:
    from analysis.config import load_machine
    from analysis.errors import AnalysisError
    from analysis.rules import (
        BaseFeedSettings,
        derive_rule,
        find_base_feed,
        plot_rule,
        save_rule,
        sweep_runs_from_files,
    )

    sweep = sweep_runs_from_files(args.runs)
    settings = BaseFeedSettings(args.slope_ratio, args.vibration_ratio, criterion=args.criterion)
    result = find_base_feed(sweep.runs, settings) if len(sweep.runs) >= 4 else None
    if args.base_feed is not None:
        base, how = args.base_feed, f"base feed {args.base_feed:g} mm/min given with --base-feed"
    elif result is not None and result.found:
        base, how = result.base_feed_mm_min, result.message
    else:
        why = result.message if result is not None else f"only {len(sweep.runs)} runs"
        raise AnalysisError(f"no base feed found: {why}. Give one with --base-feed.")
    lo = args.min_feed if args.min_feed is not None else 0.1 * base
    hi = args.max_feed if args.max_feed is not None else 3.5 * base
    if args.machine:
        m = load_machine(args.machine)
        lo, hi = max(lo, m.feed_min_mm_min), min(hi, m.feed_max_mm_min)
    ref = args.reference_load if args.reference_load is not None else sweep.reference_load_pct
    if ref is None or not math.isfinite(ref):
        raise AnalysisError(
            "the runs do not say tool and depth_mm in their conditions: give --reference-load (%)"
        )
    name = args.name or args.output.stem
    src = ", ".join(p.name for p in args.runs)
    rule = derive_rule(
        name,
        lo,
        base,
        hi,
        ref,
        exponent=args.exponent,
        n_bins=args.bins,
        description=how,  # a whole sentence already ("base feed 1000 mm/min: ...")
        source=f"feed sweep: {src}",
        tool=sweep.tool or "",
    )
    save_rule(rule, args.output)
    if args.png:
        plot_rule(rule, args.png)
    status(f"wrote {args.output} ({rule.n_bins} bins, base {base:g} mm/min at {ref:.4g} %)")
    out = {
        "rule": str(args.output),
        "name": name,
        "base_feed_mm_min": base,
        "base_feed_reason": how,
        "min_feed_mm_min": lo,
        "max_feed_mm_min": hi,
        "reference_load_pct": ref,
        "runs": [vars(r) for r in result.runs] if result else [],
        "intervals": result.table() if result else [],
        "bins": rule.table(),
    }
    if args.json:
        print_json(out)
    else:
        print(how)
        if result:
            print_table([vars(r) for r in result.runs])
            print()
            print_table(result.table())
        print()
        print_table(rule.table())
    return 0


def _add(args: argparse.Namespace) -> int:
    from analysis.errors import AnalysisError
    from analysis.rules import GroupExistsError, RuleBase, default_path

    path = args.db if args.db is not None else default_path()
    if not path.exists():
        status(f"rules add: {path} does not exist: creating a new rule base there")
    with RuleBase(path) as rb:
        try:
            gid = rb.import_file(args.rule, _key(args), note=args.note, replace=args.replace)
        except GroupExistsError as exc:
            raise AnalysisError(
                f"{exc.path}: group {exc.group_id} has this key already; add --replace to "
                "replace its rule"
            ) from None
        g = rb.get(gid)
    if args.json:
        print_json(g.summary())
    else:
        print(f"stored {args.rule} as group {gid} in {rb.path}")
    return 0


def _list(args: argparse.Namespace) -> int:
    with _open(args.db) as rb:
        rows = [g.summary() for g in rb.list()]
    if args.json:
        print_json(rows)
    else:
        print_table(rows)
    return 0


def _show(args: argparse.Namespace) -> int:
    from analysis.rules import load_rule, plot_rule

    p = Path(args.rule)
    if p.suffix == ".toml" and p.exists():
        rule, where = load_rule(p), str(p)
    else:
        with _open(args.db) as rb:
            g = rb.find(args.rule)
            rule, where = g.rule, f"group {g.id} of {rb.path}"
    if args.png:
        plot_rule(rule, args.png)
        status(f"wrote {args.png}")
    info = {
        "name": rule.name,
        "from": where,
        "min_feed_mm_min": rule.min_feed_mm_min,
        "base_feed_mm_min": rule.base_feed_mm_min,
        "max_feed_mm_min": rule.max_feed_mm_min,
        "reference_load_pct": rule.reference_load_pct,
        "exponent": rule.exponent,
        "description": rule.description,
        "source": rule.source,
        "bins": rule.table(),
    }
    if args.json:
        print_json(info)
    else:
        for k, v in info.items():
            if k != "bins":
                print(f"{k}: {v}")
        print_table(rule.table())
    return 0


def _lookup(args: argparse.Namespace) -> int:
    with _open(args.db) as rb:
        m = rb.lookup(_key(args), exact_only=args.exact)
    if args.json:
        print_json(
            {
                "exact": m.exact,
                "distance": m.distance,
                "statement": m.statement(),
                "differences": {k: list(v) for k, v in m.differences.items()},
                "group": m.group.summary(),
            }
        )
    else:
        print(m.statement())
    return 0


def _export(args: argparse.Namespace) -> int:
    with _open(args.db) as rb:
        g = rb.find(args.rule)
        rb.export(g.id, args.output)
    status(f"wrote {args.output}")
    return 0

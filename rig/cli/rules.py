"""`cutlab rules ...`: derive feed rules from feed sweeps and manage the rule base (seed 001)."""

from __future__ import annotations

import argparse
from pathlib import Path

from rig.cli.common import (
    add_catalog_options,
    count,
    image_file,
    positive,
    print_json,
    print_table,
    status,
)
from rig.cli.options import json_option, rule_db_option


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("rules", help="feed rules: derive from feed sweeps, the rule base")
    rs = p.add_subparsers(dest="rules_command", metavar="RULES_COMMAND")
    rs.required = True
    _register_derive(rs)
    _register_base(rs)


def _register_derive(rs: argparse._SubParsersAction) -> None:
    d = rs.add_parser("derive", help="base feed from a feed sweep, then the 20-bin rule")
    d.add_argument("runs", nargs="+", type=Path, help="HDF5 run files of the feed sweep")
    d.add_argument("-o", "--output", type=Path, required=True, help="rule file to write (TOML)")
    d.add_argument("--name", help="rule name (default: the output file's stem)")
    for name, text in (("--base-feed", "mm/min; skip the detection and use this"),
                       ("--min-feed", "mm/min (default: 0.1 x base, seed 001)"),
                       ("--max-feed", "mm/min (default: 3.5 x base, seed 001)")):  # fmt: skip
        d.add_argument(name, type=positive("mm/min", 200_000), help=text)
    d.add_argument("--machine", help="machine config: min/max feeds are clamped to its limits")
    d.add_argument("--reference-load", type=positive("%"),
        help="%%, load of the base-feed cut (default: a slot at the runs' depth)")  # fmt: skip
    d.add_argument("--exponent", type=positive("", 5), default=1.0,
        help="p in feed = base (L_ref/L)^p (1: constant removal rate)")  # fmt: skip
    d.add_argument("--bins", type=count(3, 200), default=20)
    d.add_argument("--slope-ratio", type=positive(), default=1.6)
    d.add_argument("--vibration-ratio", type=positive(), default=2.0)
    d.add_argument("--criterion", choices=["any", "both", "slope", "vibration"], default="any")
    d.add_argument("--png", type=image_file, help="also plot the rule and the sweep here")
    d.add_argument("--json", action="store_true")
    d.set_defaults(func=_derive)
    add_catalog_options(d)


def _key_args(q: argparse.ArgumentParser) -> None:
    q.add_argument("--part-family", required=True, help="e.g. trunk/outer/draw/lower-die")
    q.add_argument("--operation", required=True, help="roughing, pencil, rest-roughing, ...")
    q.add_argument("--tool-diameter", type=positive("mm", 1000), required=True, help="mm")
    q.add_argument("--flute-length", type=positive("mm", 1000), required=True, help="mm")
    q.add_argument("--material", required=True)
    q.add_argument("--spindle", type=positive("rpm", 100_000), required=True, help="rpm")
    q.add_argument("--depth", type=positive("mm", 1000), required=True, help="mm")
    q.add_argument("--tolerance", type=positive("mm", 100), required=True, help="mm")


def _register_base(rs: argparse._SubParsersAction) -> None:
    a = rs.add_parser("add", help="store a rule file in the rule base for a machining group")
    a.add_argument("rule", type=Path)
    _key_args(a)
    a.add_argument("--note", default="")
    a.add_argument("--replace", action="store_true", help="replace the group's existing rule")
    rule_db_option(a, "rule base (default from configs/lab.toml)")
    json_option(a, None)
    a.set_defaults(func=_add)
    ls = rs.add_parser("list", help="the machining groups in the rule base")
    rule_db_option(ls)
    json_option(ls, None)
    ls.set_defaults(func=_list)
    sh = rs.add_parser("show", help="one rule: its bins (by rule name, group id or rule file)")
    sh.add_argument("rule", help="rule name or group id in the rule base, or a rule file")
    rule_db_option(sh)
    sh.add_argument("--png", type=image_file, help="plot load vs feed with the bins")
    json_option(sh, None)
    sh.set_defaults(func=_show)
    lk = rs.add_parser("lookup", help="the rule for a job: exact key or nearest match (stated)")
    _key_args(lk)
    lk.add_argument("--exact", action="store_true", help="fail unless the key matches exactly")
    rule_db_option(lk)
    json_option(lk, None)
    lk.set_defaults(func=_lookup)
    ex = rs.add_parser("export", help="write a stored rule to a file, exactly as stored")
    ex.add_argument("rule", help="rule name or group id")
    ex.add_argument("-o", "--output", type=Path, required=True)
    rule_db_option(ex)
    ex.set_defaults(func=_export)


def _key(a: argparse.Namespace) -> dict[str, object]:
    """The machining group's key (analysis.rules.GroupKey fields) from the options."""
    return dict(part_family=a.part_family, operation=a.operation, tool_diameter_mm=a.tool_diameter,
                flute_length_mm=a.flute_length, material=a.material, spindle_rpm=a.spindle,
                depth_mm=a.depth, tolerance_mm=a.tolerance)  # fmt: skip


def _derive(a: argparse.Namespace) -> int:
    from analysis.rules import derive_from_sweep, plot_rule, save_rule

    d = derive_from_sweep(
        a.runs, a.name or a.output.stem, base_feed_mm_min=a.base_feed, min_feed_mm_min=a.min_feed,
        max_feed_mm_min=a.max_feed, machine=a.machine, reference_load_pct=a.reference_load,
        exponent=a.exponent, n_bins=a.bins, slope_ratio=a.slope_ratio,
        vibration_ratio=a.vibration_ratio, criterion=a.criterion,
    )  # fmt: skip
    save_rule(d.rule, a.output)
    if a.png:
        plot_rule(d.rule, a.png)
    out = d.summary(a.output)
    base, ref = out["base_feed_mm_min"], out["reference_load_pct"]
    status(f"wrote {a.output} ({d.rule.n_bins} bins, base {base:g} mm/min at {ref:.4g} %)")
    if a.json:
        print_json(out)
        return 0
    print(d.base_feed_reason)
    if d.detection:
        print_table(out["runs"])
        print()
        print_table(out["intervals"])
    print()
    print_table(out["bins"])
    return 0


def _add(a: argparse.Namespace) -> int:
    from analysis.rules import add_rule_file

    def creating(db: Path) -> None:
        status(f"rules add: {db} does not exist: creating a new rule base there")

    g, db = add_rule_file(a.rule, _key(a), a.db, note=a.note, replace=a.replace, on_create=creating)
    print_json(g) if a.json else print(f"stored {a.rule} as group {g['id']} in {db}")
    return 0


def _list(a: argparse.Namespace) -> int:
    from analysis.rules import list_groups

    rows = list_groups(a.db)
    print_json(rows) if a.json else print_table(rows)
    return 0


def _show(a: argparse.Namespace) -> int:
    from analysis.rules import plot_rule, rule_info

    rule, info = rule_info(a.rule, a.db)
    if a.png:
        plot_rule(rule, a.png)
        status(f"wrote {a.png}")
    if a.json:
        print_json(info)
        return 0
    print("\n".join(f"{k}: {v}" for k, v in info.items() if k != "bins"))
    print_table(info["bins"])
    return 0


def _lookup(a: argparse.Namespace) -> int:
    from analysis.rules import lookup_group

    m = lookup_group(_key(a), a.db, exact_only=a.exact)
    print_json(m) if a.json else print(m["statement"])
    return 0


def _export(a: argparse.Namespace) -> int:
    from analysis.rules import export_rule

    export_rule(a.rule, a.output, a.db)
    status(f"wrote {a.output}")
    return 0

"""`cutlab rules ...`: derive feed rules from feed sweeps and manage the rule base (seed 001)."""

from __future__ import annotations

import argparse
from pathlib import Path

from analysis import rules
from analysis.output import table_lines
from analysis.rules.request import DeriveRequest
from rig.cli.common import image_file, show, status
from rig.cli.options import REQUIRED, command, db_row, from_args, group, json_row, model_rows


# fmt: off
def register(sub: argparse._SubParsersAction) -> None:
    rs = group(sub, "rules", "feed rules: derive from feed sweeps, the rule base")
    command(rs, "derive", "base feed from a feed sweep, then the 20-bin rule",
            [model_rows(DeriveRequest), json_row(None)], _derive, catalogs=True)
    key = model_rows(rules.GroupKey, flags={"spindle_rpm": "--spindle"})  # the machining group
    command(rs, "add", "store a rule file in the rule base for a machining group", [
        ("rule", Path, None, None), key, ("--note", None, "", None),
        ("--replace", bool, None, "replace the group's existing rule"),
        db_row("rule base (default from configs/lab.toml)"), json_row(None),
    ], _add)
    command(rs, "list", "the machining groups in the rule base", [db_row(), json_row(None)], _list)
    command(rs, "show", "one rule: its bins (by rule name, group id or rule file)", [
        ("rule", None, None, "rule name or group id in the rule base, or a rule file"), db_row(),
        ("--png", image_file, None, "plot load vs feed with the bins"), json_row(None),
    ], _show)
    command(rs, "lookup", "the rule for a job: exact key or nearest match (stated)", [
        key, ("--exact", bool, None, "fail unless the key matches exactly"), db_row(),
        json_row(None),
    ], _lookup)
    command(rs, "export", "write a stored rule to a file, exactly as stored", [
        ("rule", None, None, "rule name or group id"), ("-o --output", Path, REQUIRED, None),
        db_row(),
    ], _export)
# fmt: on


def _derive(a: argparse.Namespace) -> int:
    from analysis.rules.request import derive_rule

    req = from_args(DeriveRequest, a, "rules derive")
    d = derive_rule(req)
    status(d.summary_line(req.output))
    return show(a.json, d.summary(req.output), d.lines)


def _add(a: argparse.Namespace) -> int:
    def creating(db: Path) -> None:
        status(f"rules add: {db} does not exist: creating a new rule base there")

    g, db = rules.add_rule_file(a.rule, rules.GroupKey.of(vars(a)), a.db, note=a.note,
                                replace=a.replace, on_create=creating)
    return show(a.json, g, lambda: [f"stored {a.rule} as group {g['id']} in {db}"])


def _list(a: argparse.Namespace) -> int:
    rows = rules.list_groups(a.db)
    return show(a.json, rows, lambda: table_lines(rows))


def _show(a: argparse.Namespace) -> int:
    rule, info = rules.rule_info(a.rule, a.db)
    if a.png:
        rules.plot_rule(rule, a.png)
        status(f"wrote {a.png}")
    return show(a.json, info, lambda: rules.rule_info_lines(info))


def _lookup(a: argparse.Namespace) -> int:
    m = rules.lookup_group(rules.GroupKey.of(vars(a)), a.db, exact_only=a.exact)
    return show(a.json, m, lambda: [str(m["statement"])])


def _export(a: argparse.Namespace) -> int:
    rules.export_rule(a.rule, a.output, a.db)
    status(f"wrote {a.output}")
    return 0

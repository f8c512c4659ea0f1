"""`cutlab catalog` commands: index the run files of an archive, query the index, show a run
(what each does: :mod:`analysis.catalog`)."""

from __future__ import annotations

import argparse

from rig.cli.common import print_json, print_table, show
from rig.cli.options import add_options, command, group, json_row
from rig.terminal import Progress


def _index(args: argparse.Namespace) -> int:
    from analysis.catalog import index_line, update_index

    with Progress("indexing run files", "file", quiet=args.json) as bar:
        out = update_index(args.dirs, args.index, progress=bar)
    return show(args.json, out, lambda: [index_line(out)],
                notes=lambda: [f"catalog index: {out['index']}"])  # fmt: skip


def _query(args: argparse.Namespace) -> int:
    import sys

    from analysis.catalog import catalog_named, query_rows, query_runs, records

    df = query_runs(args.expr, catalog_named(args.dir, args.index))
    if args.json:
        print_json(records(df))
    elif args.csv:
        df.to_csv(sys.stdout, index=False)
    else:
        print_table(query_rows(df, args.all_columns))
    return 0


def _show(args: argparse.Namespace) -> int:
    from analysis.catalog import catalog_named, show_lines, show_run

    row = show_run(args.run, catalog_named(args.dir, args.index))
    return show(args.json, row, lambda: show_lines(row))


# fmt: off
#: DIR and ``--index``: the catalogue a query or show reads
WHERE = [
    ("dir", None, None, "the archive folder indexed (or its index file); default: --index, else "
     "the current folder's or a parent's catalogue", {"nargs": "?", "metavar": "DIR"}),
    ("--index", None, None, "the catalogue (default: the current folder's or a parent's)",
     {"metavar": "FILE|DIR"}),
]


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    psub = group(sub, "catalog", "index an archive of run files; query it")
    command(psub, "index", "index (or update the index of) the run files under DIRs", [
        ("dirs", None, None, "folders of run files (.h5)", {"nargs": "+", "metavar": "DIR"}),
        ("--index", None, None, "the index file (default DIR/.cutlab-catalog.sqlite, the first "
         "DIR)", {"metavar": "FILE"}),
        json_row(),
    ], _index)
    q = command(psub, "query", "the runs matching an expression, one row each", [
        ("expr", None, None, "e.g. \"material == 'GM241' and 0.2 <= fz_mm <= 0.4\" ('' for all)",
         {"metavar": "EXPR"}),
        WHERE,
    ], _query)
    fmt = q.add_mutually_exclusive_group()
    add_options(fmt, [json_row(), ("--csv", bool, None, "CSV on stdout (every column)")])
    add_options(q, [("--all-columns", bool, None, "every column in the text table")])
    command(psub, "show", "one run's catalogue row", [
        ("run", None, None, "run name, CAMPAIGN/RUN, or path", {"metavar": "RUN"}), WHERE,
        json_row(),
    ], _show)
# fmt: on

"""`cutlab plan orient`: collision-free 5-axis tool orientation (seed 002); what it asks and
writes: :class:`planning.requests.OrientRequest`."""

from __future__ import annotations

import argparse

from planning.requests import OrientRequest
from rig.cli.common import bar_note, show
from rig.cli.options import command, from_args, json_row, model_rows
from rig.terminal import Progress


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``orient`` to the ``plan`` group."""
    rows = model_rows(OrientRequest, after={"out": [json_row("print the summary as JSON")]})
    command(sub, "orient", "collision-free 5-axis tool orientation (potential energy, seed 002)",
            rows, run, catalogs=True, description=OrientRequest.__doc__,
            formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip


def run(args: argparse.Namespace) -> int:
    from planning.orient import summary_lines
    from planning.requests import orient_job

    req = from_args(OrientRequest, args, "plan orient")
    with Progress("orient", "pt") as bar:  # the points planned, the bar gives way to the notes
        summary = orient_job(req, bar, bar_note(bar))
    return show(args.json, summary, lambda: summary_lines(summary))

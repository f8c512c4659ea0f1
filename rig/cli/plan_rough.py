"""`cutlab plan rough`: Z-level roughing (seed 000); what it asks and does:
:class:`planning.requests.RoughRequest`."""

from __future__ import annotations

import argparse

from planning.requests import RoughRequest
from rig.cli.common import bar_note, show
from rig.cli.options import command, from_args, json_row, model_rows
from rig.terminal import Progress


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``rough`` to the ``plan`` group."""
    rows = model_rows(RoughRequest, after={"machine": [json_row("print everything as JSON")]})
    command(sub, "rough", "Z-level roughing: levels by bisection for maximum removal rate (seed "
            "000)", rows, run, catalogs=True, description=RoughRequest.__doc__,
            formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip


def run(args: argparse.Namespace) -> int:
    from planning.limits.text import rough_text
    from planning.requests import rough_job
    from rig.cli.plan_check import WRITTEN_EXIT

    req = from_args(RoughRequest, args, "plan rough")
    with Progress("plan rough", "step") as bar:  # planned, the bar gives way to the notes
        res = rough_job(req, bar.step, bar_note(bar))
    c = res["check"]
    code = 3 if c is not None and not c["ok"] else WRITTEN_EXIT[res["verdict"]]
    return show(args.json, res, lambda: rough_text(res), code)

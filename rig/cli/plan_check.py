"""`cutlab plan check`: every block of a program against what the machine and tool can take
(:class:`planning.requests.CheckRequest`, :func:`planning.limits.check_job`)."""

from __future__ import annotations

import argparse

from planning.requests import CheckRequest
from rig.cli.common import show
from rig.cli.options import command, from_args, json_row, model_rows
from rig.terminal import Progress


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``check`` to the ``plan`` group."""
    rows = model_rows(CheckRequest, after={"plot": [json_row("machine-readable output on stdout")]})
    command(sub, "check", "check a program's blocks against machine and tool limits", rows, run,
            catalogs=True, description=CheckRequest.__doc__)  # fmt: skip


#: exit status of each verdict (0 within, 3 violations, 4 unchecked; 2 is bad input)
VERDICT_EXIT = {"within": 0, "violations": 3, "unchecked": 4}
#: exit status of the commands that write a program (plan feed, plan rough) by its verdict: 3 when
#: a block breaks a limit (the program is written, and must not pass for a good one in a script);
#: a limit not checked is printed and in the JSON, the program being what the command makes
WRITTEN_EXIT = {"within": 0, "violations": 3, "unchecked": 0}


def run(a: argparse.Namespace) -> int:
    from planning.limits.text import check_lines, stock_note
    from planning.requests import check_request

    with Progress("simulate", unit="piece") as bar:
        _, out = check_request(from_args(CheckRequest, a, "plan check"), bar)
    return show(a.json, out, lambda: check_lines(out), VERDICT_EXIT[out["verdict"]],
                notes=lambda: [stock_note(out["stock"])],
                after=[f"wrote {out['png']}" if out["png"] else None])  # fmt: skip

"""`cutlab analyze stability`: milling stability lobes; what it asks and writes:
:class:`analysis.stability_request.StabilityRequest`."""

from __future__ import annotations

import argparse

from analysis.stability_request import StabilityRequest
from rig.cli.common import noter, show
from rig.cli.options import command, from_args, json_row, model_rows


def register_stability(psub: argparse._SubParsersAction) -> None:
    """Add ``stability`` to the ``analyze`` group's subparsers."""
    command(psub, "stability", "stability lobes: chatter-free depth per spindle speed",
            [model_rows(StabilityRequest), json_row()], run, description=StabilityRequest.__doc__,
            formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip


def run(args: argparse.Namespace) -> int:
    from analysis.stability_request import stability_job

    req = from_args(StabilityRequest, args, "analyze stability")
    out, line = stability_job(req, noter("analyze stability"))
    return show(args.json, out, lambda: [line])

"""`cutlab demo` — cutlab's main job on the simulated rig: seed 003's face-milling campaign (what
it runs: :class:`rig.demo_request.DemoRequest`).

    cutlab demo                    # -> ./out/demo/facemill-ploughing/report/report.md
    cutlab demo --json             # the same figures as JSON
    cutlab demo --forces independent   # forces from rig.sim.facemill_independent (written
                                       # apart from analysis.forces) -> ./out/demo-independent
"""

from __future__ import annotations

import argparse

from rig.cli.common import show, status
from rig.cli.options import command, from_args, model_rows
from rig.demo_request import DemoRequest


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    what = "run seed 003's face-milling campaign on the simulated rig and report it"
    command(sub, "demo", what, [
        model_rows(DemoRequest), ("--json", bool, None, "machine-readable summary on stdout"),
        ("--quiet", bool, None, "no progress display"),
    ], _demo, description=DemoRequest.__doc__)  # fmt: skip


def _demo(args: argparse.Namespace) -> int:
    from rig.demo_request import demo_job
    from rig.report.demo_text import demo_lines

    res = demo_job(from_args(DemoRequest, args, "demo"), not args.quiet, status)
    if res.stopped:
        status(f"demo: stopped; run `cutlab demo --resume` to continue ({res.folder})")
        return 130
    return show(args.json, res.summary(), lambda: demo_lines(res), 0 if res.ok else 1)

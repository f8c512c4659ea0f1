"""`cutlab plan feed` and `cutlab plan simulate` (seed 001): the load-based feed post-processor
and Z-map virtual machining; what they ask is :mod:`planning.requests`, what they do
:mod:`planning.feed.job`."""

from __future__ import annotations

import argparse

from planning.requests import FeedRequest, SimulateRequest
from rig.cli.common import print_lines, show, status
from rig.cli.options import command, from_args, json_row, model_rows
from rig.terminal import Progress

#: --json, after the options feed and simulate share
JSON = {"no_holder_check": [json_row("machine-readable output on stdout")]}


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``feed`` and ``simulate`` to the ``plan`` group."""
    command(sub, "feed", "adjust feeds by predicted cutting load (seed 001)",
            model_rows(FeedRequest, after=JSON), _feed, catalogs=True,
            description=FeedRequest.__doc__)  # fmt: skip
    command(sub, "simulate", "Z-map virtual machining of a program or a plan",
            model_rows(SimulateRequest, after=JSON), _simulate, catalogs=True)  # fmt: skip


def _feed(a: argparse.Namespace) -> int:
    from planning.feed.text import feed_lines, feed_notes
    from planning.limits.text import stock_note, verdict_lines, violation_lines
    from planning.requests import feed_job
    from rig.cli.plan_check import WRITTEN_EXIT

    req = from_args(FeedRequest, a, "plan feed")
    with Progress("simulate", unit="piece") as bar:
        result, s = feed_job(req, bar, status)
    code = WRITTEN_EXIT[s["verdict"]]
    if a.json:
        s.setdefault("violations", [])  # the command contract: always a list
        return show(True, s, code=code)
    if (note := stock_note(s["stock"])) is not None:
        status(note)
    print_lines(violation_lines(s["violations"]))  # between the stock's note and the feeds' notes
    contacts = result.simulation.contacts
    return show(False, s, lambda: [*feed_lines(s), *verdict_lines(s)], code,
                notes=lambda: feed_notes(s, contacts, req.program, req.output))  # fmt: skip


def _simulate(a: argparse.Namespace) -> int:
    from planning.feed.text import simulate_lines, simulate_notes
    from planning.limits.text import stock_note
    from planning.requests import simulate_request

    req = from_args(SimulateRequest, a, "plan simulate")
    with Progress("simulate", unit="piece") as bar:
        results, out = simulate_request(req, bar)
    contacts = [r.simulation.contacts for r in results]
    return show(a.json, out, lambda: simulate_lines(out),
                notes=lambda: [stock_note(out["stock"]), *simulate_notes(out, contacts)],
                after=[f"wrote {req.png}" if req.png else None])  # fmt: skip

"""`cutlab campaign run|status|report` — run a campaign of test cuts, see where it is, report it
(:mod:`rig.campaign`, :mod:`rig.report`)."""

from __future__ import annotations

import argparse
import contextlib
from contextlib import AbstractContextManager as ContextManager
from pathlib import Path
from typing import TYPE_CHECKING

from rig.campaign_request import CampaignRunRequest
from rig.cli.common import error_line, show, status
from rig.cli.console import SERVER
from rig.cli.options import command, from_args, group, model_rows
from rig.terminal import progress_note

if TYPE_CHECKING:
    from rig.campaign.config import Campaign
    from rig.console import LiveCampaign


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    csub = group(sub, "campaign", "run a campaign of test cuts (simulated or real rig)")
    ui = [("--json", bool, None, "machine-readable summary on stdout"),
          ("--quiet", bool, None, "no progress display")]  # fmt: skip
    live = ("--live", bool, None, "serve the live console beside the campaign (--port, --bind); "
            "its address, printed, carries the session's token")  # fmt: skip
    command(csub, "run", "run (or resume) a campaign; --dry-run checks without cutting",
            [model_rows(CampaignRunRequest, after={"force_resume": ui}), live, SERVER], _run,
            catalogs=True)  # fmt: skip
    where = [("config", None, None, None), ("--out", None, None, None),
             ("--json", bool, None, None)]  # fmt: skip
    command(csub, "status", "each run's status and reason", where, _status, catalogs=True)
    command(csub, "report", "analyse a campaign's runs and write its report folder", where,
            _report, catalogs=True)  # fmt: skip


def _run(args: argparse.Namespace) -> int:
    from analysis.errors import CutlabError
    from rig.campaign import campaign_folder, dry_run
    from rig.campaign.commands import dry_run_lines, run_lines, runs_done
    from rig.campaign_request import request_campaign, run_request
    from rig.report import write_report

    req = from_args(CampaignRunRequest, args, "campaign run")
    try:
        campaign = request_campaign(req)
    except CutlabError as exc:
        if not req.dry_run:
            raise
        # the dry run lists every problem, one line each (the config's problems come joined)
        for line in filter(None, map(str.strip, str(exc).splitlines())):
            error_line(line)
        return 2
    if req.dry_run:
        progress_note("checking every program")
        d = dry_run(campaign, req.out)
        return show(args.json, d.as_dict(), lambda: dry_run_lines(d), 0 if d.ok else 2)
    progress_note(runs_done(campaign_folder(campaign, req.out), len(campaign.tests)))
    with _live(campaign, args) as live:
        on = live.run_kwargs() if live else None
        result = run_request(campaign, req, not args.quiet, on["session_factory"] if on else None,
                             on["stop"] if on else None)  # fmt: skip
    report = None if req.no_report or result.stopped else write_report(result.folder)
    show(args.json, result.summary(report.summary if report else None),
         lambda: run_lines(result, report.folder if report else None))  # fmt: skip
    if result.stopped:
        status(f"cutlab: campaign stopped; run the same command again to resume ({result.folder})")
        return 130
    return 0 if result.ok else 1


def _live(campaign: Campaign, args: argparse.Namespace) -> ContextManager[LiveCampaign | None]:
    """The live console beside the campaign with ``--live`` (its address printed), else none."""
    if not args.live:
        return contextlib.nullcontext(None)
    from rig.cli.console import warn_bind
    from rig.console import live_console

    warn_bind(args.bind)
    return live_console(campaign, args.out, port=args.port, bind=args.bind)


def _status(args: argparse.Namespace) -> int:
    from rig.campaign import campaign_status, load_campaign
    from rig.campaign.commands import missing_folder_note, status_lines

    st = campaign_status(load_campaign(args.config), args.out)
    return show(args.json, st, lambda: status_lines(st),
                after=[missing_folder_note(Path(st["folder"]))])  # fmt: skip


def _report(args: argparse.Namespace) -> int:
    from rig.campaign import campaign_folder, load_campaign
    from rig.report import write_report

    folder = campaign_folder(load_campaign(args.config), args.out)
    progress_note("analysing the runs")  # the report of a large campaign takes a while
    rep = write_report(folder)
    return show(args.json, rep.summary, lambda: [rep.markdown, f"report: {rep.folder}"])

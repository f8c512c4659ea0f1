"""`cutlab daq record`: record dynamometer forces into an HDF5 run file (:mod:`rig.recording`)."""

from __future__ import annotations

import argparse

from analysis.output import table_lines
from rig.cli.common import noter, show, status
from rig.cli.options import command, from_args, group, json_row, model_rows
from rig.recording import RecordRequest
from rig.terminal import Progress


def _record(args: argparse.Namespace) -> int:
    from rig.recording import prepare_recording

    req = from_args(RecordRequest, args, "daq record")
    recording = prepare_recording(req, noter("daq record"))
    with Progress("recording", "s", total=round(req.seconds, 3), quiet=args.quiet) as bar:
        res = recording.run(bar)
    status(f"daq record: wrote {res.path} ({res.status}{': ' + res.reason if res.reason else ''})")
    summary = res.summary()
    rows = [{"quantity": k, "value": v} for k, v in summary.items()]
    return show(args.json, summary, lambda: table_lines(rows), 0 if res.status == "success" else 1)


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    dsub = group(sub, "daq", "record dynamometer forces (NI-DAQmx or simulated)")
    command(dsub, "record", "record a run to HDF5", [
        model_rows(RecordRequest), ("--quiet", bool, None, "no progress bar"),
        json_row("summary as JSON on stdout"),
    ], _record, description=RecordRequest.__doc__)  # fmt: skip

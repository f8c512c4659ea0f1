"""`cutlab daq record`: record dynamometer forces into an HDF5 run file (:mod:`rig.log`)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from analysis.output import table_lines
from rig.cli.common import count, nonnegative, noter, positive, show, status
from rig.cli.options import REQUIRED, Rows, command, group
from rig.terminal import Progress

if TYPE_CHECKING:
    from rig.daq import Daq


def _record(args: argparse.Namespace) -> int:
    from analysis.identify.conditions_arg import parse_conditions
    from rig.log import plan_recording, record_rig

    conditions = parse_conditions(args.conditions)
    plan = plan_recording(args.rig, args.output, args.seconds, rate_hz=args.rate_hz,
                          overwrite=args.force, conditions=conditions,
                          min_free_mb=args.min_free_mb)  # fmt: skip
    for w in plan.notes:
        status(f"daq record: {w}")
    daq: Daq
    if args.sim:
        from rig.sim import SimDaq

        daq = SimDaq.from_rig(
            plan.rig, rate_hz=plan.rate_hz, seconds=plan.seconds, channels=args.channels,
            speed=args.speed, raw=args.raw, noise_v=args.sim_noise_v,
            overflow_at=args.sim_overflow_at, where=plan.where,
            warn=noter("daq record"),
        )  # fmt: skip
    else:
        from rig.daq.ni import NiDaq

        daq = NiDaq.from_rig(plan.rig, rate_hz=args.rate_hz, channels=args.channels,
                             where=plan.where)  # fmt: skip
    with Progress("recording", "s", total=round(args.seconds, 3), quiet=args.quiet) as bar:
        res = record_rig(daq, plan, flush_interval_s=args.flush_s, progress=bar)
    status(f"daq record: wrote {res.path} ({res.status}{': ' + res.reason if res.reason else ''})")
    summary = res.summary()
    rows = [{"quantity": k, "value": v} for k, v in summary.items()]
    return show(args.json, summary, lambda: table_lines(rows), 0 if res.status == "success" else 1)


# fmt: off
RECORD: Rows = (
    ("--sim", bool, None, "simulated DAQ instead of the NI device"),
    ("--seconds", positive("s", 1e6), REQUIRED, "s of acquisition"),
    ("--rate-hz", positive("Hz", 1e7), None, "Hz per channel (default: config)"),
    ("--channels", count(1, 64), None, "channel count (default: config)"),
    ("-o --output", None, REQUIRED, "run file to write (.h5)"),
    ("--rig", None, None, "rig config TOML (default configs/rig.toml)"),
    ("--speed", nonnegative("x real time", 1e6), 1.0,
     "--sim: simulated s per wall s (1 = real time, 0 = as fast as possible)"),
    ("--raw", bool, None, "--sim: store int16 ADC codes"),
    ("--sim-noise-v", nonnegative("V", 100), 0.002, "--sim: rms noise, V"),
    ("--sim-overflow-at", count(0), [], "--sim: inject a buffer overflow at these sample indices",
     {"nargs": "*"}),
    ("--flush-s", positive("s", 60), 1.0, "s between flushes (<= 60)"),
    ("--conditions", None, [], "cutting conditions as KEY=VALUE pairs (spindle_rpm=600 "
     "tool=phi10-flat; numbers stored as numbers) or one JSON object ('{\"feed_mm_min\": 300}')",
     {"nargs": "+", "metavar": "KEY=VALUE"}),
    ("--min-free-mb", nonnegative("MB", 1e6), 64.0, "MB to keep free on the file's disk: a "
     "recording that would need them does not start, one that reaches them stops cleanly "
     "(default 64)"),
    ("--force", bool, None, "overwrite an existing file"),
    ("--quiet", bool, None, "no progress bar"),
    ("--json", bool, None, "summary as JSON on stdout"),
)
# fmt: on


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    dsub = group(sub, "daq", "record dynamometer forces (NI-DAQmx or simulated)")
    command(dsub, "record", "record a run to HDF5", RECORD, _record, description="Record the "
            "dynamometer into an HDF5 run file (see `cutlab data info`).")  # fmt: skip

"""`cutlab daq` commands: record dynamometer forces into an HDF5 run file.

cutlab daq record --sim --seconds 5 --rate-hz 20000 --channels 3 -o run.h5
cutlab daq record --seconds 5 -o run.h5                 # the NI device of configs/rig.toml
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from rig.cli.common import count, nonnegative, positive  # isort: split

from rig.cli.common import print_json, print_table, status
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
            warn=lambda msg: status(f"daq record: {msg}"),
        )  # fmt: skip
    else:
        from rig.daq.ni import NiDaq

        daq = NiDaq.from_rig(plan.rig, rate_hz=args.rate_hz, channels=args.channels,
                             where=plan.where)  # fmt: skip
    with Progress("recording", "s", total=round(args.seconds, 3), quiet=args.quiet) as bar:
        res = record_rig(daq, plan, flush_interval_s=args.flush_s, progress=bar)
    status(f"daq record: wrote {res.path} ({res.status}{': ' + res.reason if res.reason else ''})")
    summary = res.summary()
    if args.json:
        print_json(summary)
    else:
        print_table([{"quantity": k, "value": v} for k, v in summary.items()])
    return 0 if res.status == "success" else 1


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    p = sub.add_parser("daq", help="record dynamometer forces (NI-DAQmx or simulated)")
    psub = p.add_subparsers(dest="daq_command", metavar="DAQ_COMMAND")
    psub.required = True
    r = psub.add_parser("record", help="record a run to HDF5", description="Record the "
                        "dynamometer into an HDF5 run file (see `cutlab data info`).")  # fmt: skip
    add = r.add_argument
    add("--sim", action="store_true", help="simulated DAQ instead of the NI device")
    add("--seconds", type=positive("s", 1e6), required=True, help="s of acquisition")
    add(
        "--rate-hz", type=positive("Hz", 1e7), default=None, help="Hz per channel (default: config)"
    )
    add("--channels", type=count(1, 64), default=None, help="channel count (default: config)")
    add("-o", "--output", required=True, help="run file to write (.h5)")
    add("--rig", default=None, help="rig config TOML (default configs/rig.toml)")
    add("--speed", type=nonnegative("x real time", 1e6), default=1.0,
        help="--sim: simulated s per wall s (1 = real time, 0 = as fast as possible)")  # fmt: skip
    add("--raw", action="store_true", help="--sim: store int16 ADC codes")
    add("--sim-noise-v", type=nonnegative("V", 100), default=0.002, help="--sim: rms noise, V")
    add("--sim-overflow-at", type=count(0), nargs="*", default=[],
        help="--sim: inject a buffer overflow at these sample indices")  # fmt: skip
    add("--flush-s", type=positive("s", 60), default=1.0, help="s between flushes (<= 60)")
    add("--conditions", nargs="+", default=[], metavar="KEY=VALUE",
        help="cutting conditions as KEY=VALUE pairs (spindle_rpm=600 tool=phi10-flat; numbers "
        "stored as numbers) or one JSON object ('{\"feed_mm_min\": 300}')")  # fmt: skip
    add("--min-free-mb", type=nonnegative("MB", 1e6), default=64.0,
        help="MB to keep free on the file's disk: a recording that would need them does not "
        "start, one that reaches them stops cleanly (default 64)")  # fmt: skip
    add("--force", action="store_true", help="overwrite an existing file")
    add("--quiet", action="store_true", help="no progress bar")
    add("--json", action="store_true", help="summary as JSON on stdout")
    r.set_defaults(func=_record)

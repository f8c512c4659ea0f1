"""`cutlab daq` commands: record dynamometer forces into an HDF5 run file.

cutlab daq record --sim --seconds 5 --rate-hz 20000 --channels 3 -o run.h5
cutlab daq record --seconds 5 -o run.h5                 # the NI device of configs/rig.toml
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path


def _record(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from analysis.config import load_rig
    from analysis.errors import ConfigError
    from rig.cli._common import print_json, print_table, status
    from rig.daq import Calibration
    from rig.log.record import aliasing_warning, milling_force_source, record

    rig_path = args.rig
    rig = load_rig(rig_path)
    where = str(rig_path or "configs/rig.toml")
    if not args.seconds > 0:
        raise ConfigError(f"--seconds = {args.seconds}: must be > 0 (s)")
    from rig.cli._common import parse_conditions

    conditions = parse_conditions(args.conditions)
    rate_hz = float(args.rate_hz or rig.daq.rate_hz)
    if not 0 < rate_hz <= 10_000_000:
        raise ConfigError(f"--rate-hz = {rate_hz}: must be in (0, 1e7] Hz")
    out = Path(args.output)
    if out.exists() and not args.force:  # before any device is opened
        raise ConfigError(f"{out}: file exists; --force overwrites it")
    notes = [w for w in [aliasing_warning(rate_hz, rig.dynamometer)] if w]
    for w in notes:
        status(f"daq record: {w}")

    if args.sim:
        from rig.sim import SimClock, SimDaq

        n = int(args.channels or len(rig.daq.channels))
        if not 1 <= n <= 64:
            raise ConfigError(f"--channels = {n}: must be 1..64")
        cal = None
        if n == len(rig.dynamometer.channels):
            cal = Calibration.from_dynamometer(rig.dynamometer, n, where)
        else:
            status(
                f"daq record: {n} channels but the dynamometer in {where} has "
                f"{len(rig.dynamometer.channels)}: recording volts without a calibration"
            )
        clock = SimClock(args.speed) if args.speed > 0 else None
        daq = SimDaq(
            milling_force_source(cal, n),
            rate_hz=rate_hz,
            channels=tuple(f"sim/ai{i}" for i in range(n)),
            channel_names=cal.channel_names if cal else None,
            clock=clock,
            read_interval_s=rig.daq.read_interval_s,
            seconds=args.seconds,
            sample_format="raw_int16" if args.raw else "volts_float64",
            input_range_v=rig.daq.input_range_v,
            sim_noise_v=args.sim_noise_v,
            sim_overflow_at=args.sim_overflow_at,
        )
        run_clock = clock.now if clock is not None else (lambda: 0.0)
        rig_meta = {"daq": "simulated", "dynamometer": rig.dynamometer.model}
    else:
        from rig.daq.ni import NiDaq

        cfg = rig.daq
        if args.rate_hz:
            cfg = cfg.model_copy(update={"rate_hz": rate_hz})
        if args.channels:
            if args.channels > len(cfg.channels):
                raise ConfigError(
                    f"--channels = {args.channels}: {where} lists only {len(cfg.channels)} "
                    f"daq.channels"
                )
            cfg = cfg.model_copy(update={"channels": cfg.channels[: args.channels]})
        cal = Calibration.from_dynamometer(rig.dynamometer, len(cfg.channels), where)
        daq = NiDaq(cfg, cal.channel_names)
        run_clock = time.monotonic
        rig_meta = {"daq": cfg.model_dump(), "dynamometer": rig.dynamometer.model}
    if cal is not None:
        rig_meta["calibration_id"] = cal.calibration_id

    # disable=None: tqdm turns itself off when stderr is not a terminal (CI logs)
    bar = tqdm(total=round(args.seconds, 3), unit="s", desc="recording",
               disable=True if args.quiet else None)  # fmt: skip

    def progress(t: float) -> None:
        bar.n = round(min(t, args.seconds), 3)
        bar.refresh()

    try:
        res = record(
            daq,
            out,
            args.seconds,
            calibration=cal,
            clock=run_clock,
            flush_interval_s=args.flush_s,
            overwrite=args.force,
            conditions=conditions,
            rig=rig_meta,
            progress=progress,
            notes=notes,
        )
        progress(res.samples_acquired / daq.info.rate_hz)
    finally:
        bar.close()
    summary = {
        "file": str(res.path),
        "status": res.status,
        "reason": res.reason,
        "channels": list(daq.info.channel_names),
        "rate_hz": daq.info.rate_hz,
        "samples_acquired": res.samples_acquired,
        "samples_written": res.writer.samples_written,
        "samples_dropped": res.writer.samples_dropped,
        "samples_missing": res.writer.samples_missing,
        "duration_s": res.samples_acquired / daq.info.rate_hz,
    }
    status(f"daq record: wrote {out} ({res.status}{': ' + res.reason if res.reason else ''})")
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
    r = psub.add_parser(
        "record",
        help="record a run to HDF5",
        description="Record the dynamometer into an HDF5 run file (see `cutlab data info`).",
    )
    r.add_argument("--sim", action="store_true", help="simulated DAQ instead of the NI device")
    r.add_argument("--seconds", type=float, required=True, help="s of acquisition")
    r.add_argument("--rate-hz", type=float, default=None, help="Hz per channel (default: config)")
    r.add_argument("--channels", type=int, default=None, help="channel count (default: config)")
    r.add_argument("-o", "--output", required=True, help="run file to write (.h5)")
    r.add_argument("--rig", default=None, help="rig config TOML (default configs/rig.toml)")
    r.add_argument(
        "--speed",
        type=float,
        default=1.0,
        help="--sim: simulated s per wall s (1 = real time, 0 = as fast as possible)",
    )
    r.add_argument("--raw", action="store_true", help="--sim: store int16 ADC codes")
    r.add_argument("--sim-noise-v", type=float, default=0.002, help="--sim: rms noise, V")
    r.add_argument(
        "--sim-overflow-at",
        type=int,
        nargs="*",
        default=[],
        help="--sim: inject a buffer overflow at these sample indices",
    )
    r.add_argument("--flush-s", type=float, default=1.0, help="s between flushes (<= 60)")
    r.add_argument(
        "--conditions",
        nargs="+",
        default=[],
        metavar="KEY=VALUE",
        help="cutting conditions as KEY=VALUE pairs (spindle_rpm=600 tool=phi10-flat; numbers "
        "stored as numbers) or one JSON object ('{\"feed_mm_min\": 300}')",
    )
    r.add_argument("--force", action="store_true", help="overwrite an existing file")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.add_argument("--json", action="store_true", help="summary as JSON on stdout")
    r.set_defaults(func=_record)

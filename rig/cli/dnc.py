"""`cutlab dnc` commands: stream a program to a controller, run a simulated controller."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from rig.cli._common import print_json, status

PROTOCOLS = ("fanuc", "grbl")
DEFAULT_MACHINE = {"fanuc": "ace-h63", "grbl": "lab-grbl"}


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    p = sub.add_parser(
        "dnc", help="DNC streaming (Fanuc drip feed, GRBL) and simulated controllers"
    )
    dsub = p.add_subparsers(dest="dnc_command", metavar="DNC_COMMAND")
    dsub.required = True

    s = dsub.add_parser("send", help="stream an NC program to a controller over serial")
    s.add_argument("file", help="NC program")
    s.add_argument("--port", help="port name or pyserial URL (default: the machine config's)")
    s.add_argument("--protocol", required=True, help="fanuc or grbl")
    s.add_argument("--machine", help="machine name or TOML (default ace-h63 / lab-grbl)")
    s.add_argument("--baud", type=int, help="override serial.baudrate")
    s.add_argument("--timeout", type=float, help="override serial.timeout_s, s")
    s.add_argument("--start-block", type=int, default=0, help="restart at this block (0-based)")
    s.add_argument("--safe-z", type=float, help="restart: Z to approach from, mm")
    s.add_argument("--mode", default="char-counting", help="GRBL: char-counting | send-response")
    s.add_argument("--unlock", action="store_true", help="GRBL: send $X if it is in Alarm")
    s.add_argument("--no-wait-dc1", action="store_true", help="Fanuc: send without waiting for DC1")
    s.add_argument("--record", help="write the block record to this CSV file")
    s.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    s.add_argument("--json", action="store_true", help="end with a JSON summary on stdout")
    s.set_defaults(func=_send)

    r = dsub.add_parser("serve", help="answer remote program requests from a Fanuc control")
    r.add_argument("--port", help="port name or pyserial URL (default: the machine config's)")
    r.add_argument("--machine", help="machine name or TOML (default ace-h63)")
    r.add_argument("--folder", help="program folder (default: serial.program_folder)")
    r.add_argument("--once", action="store_true", help="serve one request, then exit")
    r.add_argument("--json", action="store_true", help="a JSON summary per request on stdout")
    r.set_defaults(func=_serve)

    c = dsub.add_parser("sim-controller", help="run a simulated controller on a pseudo-terminal")
    c.add_argument("--protocol", required=True, help="fanuc or grbl")
    c.add_argument("--machine", help="machine name or TOML (default ace-h63 / lab-grbl)")
    c.add_argument("--baud", type=int, help="emulated baud rate (default: the machine config's)")
    c.add_argument("--speed", type=float, default=1.0, help="simulated s per wall s")
    c.add_argument("--duration", type=float, help="stop after this many wall s (default: Ctrl-C)")
    c.add_argument(
        "--sim",
        action="append",
        default=[],
        metavar="KNOB=VALUE",
        help="fault knob, e.g. stop_answering_after_block=100, alarm_at_block=50,2",
    )
    c.add_argument("--json", action="store_true", help="end with a JSON summary on stdout")
    c.set_defaults(func=_sim_controller)


def _protocol(name: str) -> str:
    from rig.dnc.port import check_protocol

    return check_protocol(name)


def _machine(name: str | None, protocol: str):  # noqa: ANN202
    from analysis.config import load_machine
    from rig.dnc import DncError

    m = load_machine(name or DEFAULT_MACHINE[protocol])
    if m.dialect != protocol:
        raise DncError(
            f"machine {m.name!r} has dialect = {m.dialect!r} but --protocol is {protocol!r}; "
            f"pick a {protocol} machine (e.g. --machine {DEFAULT_MACHINE[protocol]})"
        )
    return m


def _serial(machine, port: str | None, baud: int | None, timeout: float | None):  # noqa: ANN001, ANN202
    from analysis.config import SerialConfig, validate

    data: dict[str, Any] = machine.serial.model_dump()
    if port is not None:
        data["port"] = port
    if baud is not None:
        data["baudrate"] = baud
    if timeout is not None:
        data["timeout_s"] = timeout
    return validate(SerialConfig, data, f"machine {machine.name} serial (with command options)")


def _send(args: argparse.Namespace) -> int:
    from rig.dnc import (
        CsvSink,
        FanucStreamer,
        GrblStreamer,
        MemorySink,
        StreamFault,
        load_program,
        restart_blocks,
    )

    protocol = _protocol(args.protocol)
    machine = _machine(args.machine, protocol)
    cfg = _serial(machine, args.port, args.baud, args.timeout)
    from rig.dnc.port import check_settings

    check_settings(cfg, protocol)
    program = load_program(args.file)  # NC errors are reported here, before the port is opened
    pre = restart_blocks(program, args.start_block, protocol, machine, args.safe_z)
    sink = CsvSink(args.record) if args.record else MemorySink()
    show = not args.no_progress and sys.stderr.isatty()
    if protocol == "fanuc":
        st = FanucStreamer(cfg, sink=sink, progress=show, wait_for_dc1=not args.no_wait_dc1)
    else:
        st = GrblStreamer(cfg, sink=sink, progress=show, mode=args.mode, unlock=args.unlock)
    status(f"sending {program.name} ({len(program)} blocks) to {cfg.port} [{protocol}]")
    try:
        res = st.send(program, args.start_block, pre)
    except StreamFault as exc:
        if args.json:
            print_json(exc.result.as_dict())
        raise
    if args.json:
        print_json(res.as_dict())
    else:
        status(
            f"sent {res.blocks_sent} blocks, {res.bytes_sent} bytes in {res.seconds:.1f} s "
            f"({res.bytes_per_s:,.0f} B/s of {res.line_bytes_per_s:,.0f}); last acknowledged "
            f"block {res.last_acknowledged_block}"
        )
    return 0


def _serve(args: argparse.Namespace) -> int:
    from rig.dnc import RemoteServer

    machine = _machine(args.machine, "fanuc")
    cfg = _serial(machine, args.port, None, None)
    srv = RemoteServer(cfg, args.folder, machine=machine, on_listening=lambda: status(
        f"listening for a remote request on {cfg.port} (programs from {srv.folder})"
    ))  # fmt: skip
    while True:
        res = srv.serve_one()
        req = srv.request
        if args.json:
            print_json({"program": req.program, "start_block": req.start_block, **res.as_dict()})
        else:
            status(f"sent {req.program} from block {req.start_block}: {res.blocks_sent} blocks")
        if args.once:
            return 0


def _knobs(items: list[str]) -> dict[str, Any]:
    from rig.dnc import DncError

    out: dict[str, Any] = {}
    for it in items:
        key, sep, val = it.partition("=")
        key = key.strip().removeprefix("sim_")
        if not sep or not val:
            raise DncError(f"--sim {it!r}: expected KNOB=VALUE, e.g. alarm_at_block=50,2")
        try:
            nums = tuple(float(v) if key.endswith("_s") and i == 0 else int(v)
                         for i, v in enumerate(val.split(",")))  # fmt: skip
        except ValueError:
            raise DncError(f"--sim {it!r}: value must be a number or two (k,code)") from None
        out[f"sim_{key}"] = nums[0] if len(nums) == 1 else nums
    return out


def _check_knobs(knobs: dict[str, Any], protocol: str) -> None:
    """Refuse a knob the controller class does not take, listing the ones it does (the
    ``sim_*`` keyword parameters of its ``__init__`` and its bases')."""
    import inspect

    from rig.dnc import DncError

    if protocol == "fanuc":
        from rig.sim import SimFanuc as cls
    else:
        from rig.sim import SimGrbl as cls
    valid = sorted(
        {
            name.removeprefix("sim_")
            for klass in cls.__mro__
            if "__init__" in vars(klass)
            for name in inspect.signature(klass.__init__).parameters
            if name.startswith("sim_")
        }
    )
    bad = [k.removeprefix("sim_") for k in knobs if k.removeprefix("sim_") not in valid]
    if bad:
        raise DncError(
            f"--sim {bad[0]}: unknown knob for the {protocol} controller; valid knobs: "
            + ", ".join(valid)
        )


def _sim_controller(args: argparse.Namespace) -> int:
    import signal
    import threading

    from rig.dnc import DncError
    from rig.sim import SimClock

    protocol = _protocol(args.protocol)
    machine = _machine(args.machine, protocol)
    knobs = _knobs(args.sim)
    _check_knobs(knobs, protocol)
    baud = args.baud or machine.serial.baudrate
    clock = SimClock(args.speed) if args.speed > 0 else None
    if clock is None:
        raise DncError(f"--speed = {args.speed}: must be > 0 (simulated s per wall s)")
    try:
        if protocol == "fanuc":
            from rig.sim import SimFanuc

            s = machine.serial
            ctl = SimFanuc(
                machine,
                clock=clock,
                baudrate=baud,
                bytesize=s.bytesize,
                parity=s.parity,
                stopbits=s.stopbits,
                flow_control=s.flow_control,
                **knobs,
            )
        else:
            from rig.sim import SimGrbl

            ctl = SimGrbl(machine, clock=clock, baudrate=baud, **knobs)
    except TypeError as exc:  # a knob of the right name but an unusable value
        raise DncError(f"--sim: the {protocol} controller refused the knobs ({exc})") from None
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())  # before the path is out: a script
    path = ctl.start()  # may stop us as soon as it has read it
    print(path, flush=True)
    status(f"simulated {protocol} controller on {path} ({baud} baud, speed x{args.speed:g})")
    try:
        stop.wait(args.duration)
    except KeyboardInterrupt:
        pass
    finally:
        ctl.stop()
    summary = {
        "path": path,
        "bytes_received": len(ctl.received),
        "sha256": ctl.received_sha256(),
        "blocks_executed": len(ctl.executed),
        "last_completed_block": ctl.last_completed_block,
        "starved_fraction": ctl.starved_fraction,
        "overruns": ctl.overruns,
        "framing_errors": ctl.framing_errors,
        "alarm": ctl.alarm,
    }
    if protocol == "fanuc":
        summary |= {"xoff_count": ctl.xoff_count, "max_chars_after_xoff": ctl.max_after_xoff}
    else:
        summary |= {"planner_full_waits": ctl.planner_waits, "errors": len(ctl.errors)}
    if args.json:
        print_json(summary)
    else:
        status(", ".join(f"{k} {v}" for k, v in summary.items()))
    return 0

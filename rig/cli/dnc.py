"""`cutlab dnc` commands: stream a program to a controller, unlock or reset a GRBL, run a simulated
controller."""

from __future__ import annotations

import argparse

from rig.cli.common import noter, positive, print_json, show, status
from rig.cli.options import command, from_args, group, json_row, model_rows, serial_rows
from rig.send_request import SendRequest

#: the link's fields of a send, options shared by the dnc commands (serial_rows)
SERIAL = ("port", "protocol", "machine", "baud", "timeout")


def _send(args: argparse.Namespace) -> int:
    from rig.dnc.preview import preview, preview_lines
    from rig.dnc.session import send_under_control
    from rig.send_request import adaptive_loop, prepare

    req = from_args(SendRequest, args, "dnc send")
    job = prepare(req)
    if job.start_block:
        status(f"restart at block {job.start_block}: " + "; ".join(job.restart_notes))
    if req.dry_run:  # what a send would send first; nothing is opened or sent
        p = preview(job)
        return show(args.json, p, lambda: preview_lines(p),
                    after=[f"dry run: nothing was sent to {job.settings.port}"])  # fmt: skip
    # the DAQ started and zeroed before anything is sent: no force, no send
    loop = adaptive_loop(job, req, noter("dnc send")).start() if req.adaptive else None
    status(f"sending {job.program.name} ({len(job.program)} blocks) to {job.settings.port} "
           f"[{job.protocol}]")  # fmt: skip
    on_fault = (lambda o: print_json(o.as_dict())) if args.json else None
    out = send_under_control(job, loop, on_fault=on_fault)
    print_json(out.as_dict()) if args.json else status(out.result.summary_line())
    return 0


def _serve(args: argparse.Namespace) -> int:
    from rig.dnc import remote_server

    def listening(port: str, folder: object) -> None:
        status(f"listening for a remote request on {port} (programs from {folder})")

    srv = remote_server(args.machine, args.port, args.folder, on_listening=listening)
    while True:
        res = srv.serve_one()
        req = srv.request
        assert req is not None  # serve_one returns after answering a request
        if args.json:
            print_json({"program": req.program, "start_block": req.start_block, **res.as_dict()})
        else:
            status(f"sent {req.program} from block {req.start_block}: {res.blocks_sent} blocks")
        if args.once:
            return 0


def _grbl(args: argparse.Namespace) -> int:
    from rig.dnc import dnc_machine, grbl_command, serial_settings

    _, machine = dnc_machine("grbl", args.machine)
    cfg = serial_settings(machine, args.port, args.baud, args.timeout)
    reply = grbl_command(cfg, args.dnc_command)
    print_json(reply.as_dict()) if args.json else status("\n".join(reply.status_lines()))
    return 0 if reply.ok or args.dnc_command == "status" else 1


def _sim_controller(args: argparse.Namespace) -> int:
    from rig.dnc import dnc_machine
    from rig.sim import run_controller, sim_controller

    protocol, machine = dnc_machine(args.protocol, args.machine)
    ctl = sim_controller(protocol, machine, speed=args.speed, baud=args.baud, knobs=args.sim)

    def started(path: str) -> None:
        print(path, flush=True)
        status(f"simulated {protocol} controller on {path} ({ctl.baudrate} baud, "
               f"speed x{args.speed:g})")  # fmt: skip

    summary = run_controller(ctl, args.duration, on_started=started)
    print_json(summary) if args.json else status(", ".join(f"{k} {v}" for k, v in summary.items()))
    return 0


# fmt: off
def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    from rig.dnc.keys import HELP as KEYS_HELP

    dsub = group(sub, "dnc", "DNC streaming (Fanuc drip feed, GRBL) and simulated controllers")
    link = serial_rows("machine name or TOML (default ace-h63 / lab-grbl)", protocol=True)
    send = model_rows(SendRequest, skip=SERIAL, after={"file": link})
    command(dsub, "send", "stream an NC program to a controller over serial", [
        send, json_row("end with a JSON summary on stdout"),
    ], _send, description=(SendRequest.__doc__ or "").format(keys=KEYS_HELP))
    for name, text in (
        ("unlock", "GRBL: leave the Alarm state ($X) after checking the machine"),
        ("reset", "GRBL: clean soft reset (feed hold and Hold:0 first if it moves)"),
    ):
        command(dsub, name, text, [serial_rows("machine name or TOML (default lab-grbl)"),
                                   json_row("a JSON reply on stdout")], _grbl)
    command(dsub, "serve", "answer remote program requests from a Fanuc control", [
        serial_rows("machine name or TOML (default ace-h63)", baud_help=None, timeout=False),
        ("--folder", None, None, "program folder (default: serial.program_folder)"),
        ("--once", bool, None, "serve one request, then exit"),
        json_row("a JSON summary per request on stdout"),
    ], _serve)
    command(dsub, "sim-controller", "run a simulated controller on a pseudo-terminal", [
        serial_rows("machine name or TOML (default ace-h63 / lab-grbl)", port=False,
                    protocol=True, baud_help="emulated baud rate (default: the machine config's)",
                    timeout=False),
        ("--speed", positive("x real time", 1e6), 1.0, "simulated s per wall s"),
        ("--duration", positive("s"), None, "stop after this many wall s (default: Ctrl-C)"),
        ("--sim", None, [], "fault knob, e.g. stop_answering_after_block=100, alarm_at_block=50,2",
         {"action": "append", "metavar": "KNOB=VALUE"}),
        json_row("end with a JSON summary on stdout"),
    ], _sim_controller)
# fmt: on

"""`cutlab dnc` commands: stream a program to a controller, unlock or reset a GRBL, run a simulated
controller."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from rig.cli.common import count, noter, number, positive, print_json, show, status
from rig.cli.options import command, group, json_row, rig_row, serial_rows

if TYPE_CHECKING:
    from rig.adaptive.send import SendLoop
    from rig.dnc import SendJob

# fmt: off
SEND = (
    ("--start-block", count(0), 0, "restart at this block (0-based)"),
    ("--safe-z", number("mm"), None, "restart: clearance Z to approach from, mm (default: the "
     "program's)"),
    ("--plunge-feed", positive("mm/min", 200_000), None, "restart: feed down to the restart "
     "point, mm/min (default: the program's last plunge before the block)"),
    ("--dry-run", bool, None, "print the restart preamble and the first blocks that would be "
     "sent; send nothing"),
    ("--mode", None, "char-counting", "GRBL: char-counting | send-response"),
    ("--unlock", bool, None, "GRBL: send $X if it is in Alarm"),
    ("--no-strip", bool, None, "GRBL: send lines as written (default: no comments, spaces, N and "
     "O words)"),
    ("--no-wait-dc1", bool, None, "Fanuc: send without waiting for DC1"),
    ("--adaptive", ("feed", "spindle", "both"), None, "GRBL: hold a force target with real-time "
     "overrides (refused for controllers without a real-time override, the Fanuc drip feed)"),
    ("--target-force", positive("N", 1e6), None,
     "--adaptive: per-revolution mean |Fxy| to hold, N"),
    ("--max-force", positive("N", 1e6), None, "--adaptive: resultant force that holds the feed, N"),
    ("--spindle-rpm", positive("rpm", 1e6), None, "--adaptive: the program's spindle speed, rpm"),
    ("--stall-revs", positive("revolutions", 1e4), 3.0, "--adaptive: revolutions without a DAQ "
     "block, beyond one block, before the loop counts the force signal lost and holds (default 3)"),
)
# fmt: on


def _send(args: argparse.Namespace) -> int:
    from rig.dnc import prepare_send
    from rig.dnc.preview import preview, preview_lines
    from rig.dnc.session import send_under_control

    if args.adaptive:
        from rig.adaptive.send_options import check_send_adaptive

        check_send_adaptive(args.adaptive, args.protocol, args.machine, args.target_force,
                            args.max_force, args.spindle_rpm)  # fmt: skip
    job = prepare_send(
        args.file, args.protocol, machine=args.machine, port=args.port, baud=args.baud,
        timeout_s=args.timeout, start_block=args.start_block, safe_z_mm=args.safe_z,
        plunge_feed_mm_min=args.plunge_feed,
        record_csv=None if args.dry_run else args.record, progress=not args.no_progress,
        grbl_mode=args.mode, grbl_unlock=args.unlock, grbl_strip=not args.no_strip,
        fanuc_wait_dc1=not args.no_wait_dc1, guard=not args.dry_run,
    )  # fmt: skip
    if job.start_block:
        status(f"restart at block {job.start_block}: " + "; ".join(job.restart_notes))
    if args.dry_run:  # what a send would send first; nothing is opened or sent
        p = preview(job)
        return show(args.json, p, lambda: preview_lines(p),
                    after=[f"dry run: nothing was sent to {job.settings.port}"])  # fmt: skip
    # the DAQ started and zeroed before anything is sent: no force, no send
    loop = _adaptive_loop(job, args).start() if args.adaptive else None
    status(f"sending {job.program.name} ({len(job.program)} blocks) to {job.settings.port} "
           f"[{job.protocol}]")  # fmt: skip
    on_fault = (lambda o: print_json(o.as_dict())) if args.json else None
    out = send_under_control(job, loop, on_fault=on_fault)
    print_json(out.as_dict()) if args.json else status(out.result.summary_line())
    return 0


def _adaptive_loop(job: SendJob, args: argparse.Namespace) -> SendLoop:
    """The rig's DAQ opened and zeroed, the loop on the send's streamer (rig.adaptive.send)."""
    from rig.adaptive import AdaptiveSettings
    from rig.adaptive.send import SendLoop

    settings = AdaptiveSettings(mode=args.adaptive, target_force_n=args.target_force,
                                max_force_n=args.max_force, stall_revs=args.stall_revs)  # fmt: skip
    return SendLoop(job, settings, args.spindle_rpm, rig=args.rig, say=noter("dnc send"))


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


SEND_HELP = (
    "Stream an NC program to a controller over serial. Operator control, {keys}: each action is "
    "one status line on stderr and is recorded (--json: operator_actions). GRBL: hold is '!', "
    "resume '~', abort '!' then Hold:0 then a soft reset; Fanuc drip feed: the line takes no "
    "feed hold, press FEED HOLD / CYCLE START on the control, abort stops feeding. A restart "
    "(--start-block) approaches at the program's clearance (its highest rapid before the block, "
    "or the R plane; --safe-z overrides) and plunges at the program's plunge feed (--plunge-feed "
    "if it has none)."
)


# fmt: off
def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    from rig.dnc.keys import HELP as KEYS_HELP

    dsub = group(sub, "dnc", "DNC streaming (Fanuc drip feed, GRBL) and simulated controllers")
    command(dsub, "send", "stream an NC program to a controller over serial", [
        ("file", None, None, "NC program"),
        serial_rows("machine name or TOML (default ace-h63 / lab-grbl)", protocol=True), SEND,
        rig_row("--adaptive: the DAQ's rig TOML (default configs/rig.toml)"),
        ("--record", None, None, "write the block record to this CSV file"),
        ("--no-progress", bool, None, "no progress bar on stderr"),
        json_row("end with a JSON summary on stdout"),
    ], _send, description=SEND_HELP.format(keys=KEYS_HELP))
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

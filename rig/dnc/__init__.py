"""DNC streaming: NC programs to a controller over RS-232 (Fanuc drip feed, GRBL).

Quick tour::

    from analysis.config import load_machine
    from rig.dnc import FanucStreamer, GrblStreamer, load_program, restart_blocks, CsvSink

    machine = load_machine("ace-h63")
    program = load_program("part.nc")              # NC errors raise here, before sending
    st = FanucStreamer(machine.serial, sink=CsvSink("blocks.csv"))
    result = st.send(program)                      # StreamResult; StreamFault on a fault
    plan = restart_plan(program, 120, "fanuc", machine)   # arcs, cycles made complete
    st.send(program, start_block=120, preamble=plan.preamble, replaced=plan.replaced)

Modules: :mod:`~rig.dnc.protocols` (each protocol's rules, :func:`protocol_of`),
:mod:`~rig.dnc.port` (settings per protocol, opening), :mod:`~rig.dnc.link` (reader thread,
DC1/DC3 gate, pacing), :mod:`~rig.dnc.fanuc`, :mod:`~rig.dnc.eia` (EIA tape code),
:mod:`~rig.dnc.grbl`, :mod:`~rig.dnc.sinks` (the record into a run file),
:mod:`~rig.dnc.restart`, :mod:`~rig.dnc.remote` (remote program request),
:mod:`~rig.dnc.record` (the block record and its sinks), :mod:`~rig.dnc.progress`,
:mod:`~rig.dnc.program`, :mod:`~rig.dnc.connect` (machine, settings and streamer from a
command's options), :mod:`~rig.dnc.execution` (the block executing, from status reports or
timing), :mod:`~rig.dnc.guard` (signals and a watchdog hold the feed),
:mod:`~rig.dnc.console` (GRBL unlock / reset / status), :mod:`~rig.dnc.errors`. The simulated
controllers that speak these protocols on a pseudo-terminal are :mod:`rig.sim.fanuc` and
:mod:`rig.sim.grbl`.
"""

from rig.dnc.connect import (
    SendJob,
    dnc_machine,
    prepare_send,
    remote_server,
    serial_settings,
    streamer_class,
)
from rig.dnc.console import GrblReply, grbl_command
from rig.dnc.errors import DncError, StreamFault
from rig.dnc.fanuc import FanucStreamer
from rig.dnc.grbl import GrblStatus, GrblStreamer, parse_status
from rig.dnc.guard import HoldGuard, halt_on_signals
from rig.dnc.program import Block, Program, load_program, program_from_text
from rig.dnc.protocols import StreamProtocol, protocol_of
from rig.dnc.record import BlockRow, BlockSink, CsvSink, MemorySink, read_csv_record
from rig.dnc.remote import RemoteServer, parse_request
from rig.dnc.restart import RestartPlan, restart_blocks, restart_plan
from rig.dnc.result import StreamResult

__all__ = [
    "Block",
    "BlockRow",
    "BlockSink",
    "CsvSink",
    "DncError",
    "FanucStreamer",
    "GrblReply",
    "GrblStatus",
    "GrblStreamer",
    "HoldGuard",
    "MemorySink",
    "Program",
    "RemoteServer",
    "RestartPlan",
    "SendJob",
    "StreamFault",
    "StreamProtocol",
    "StreamResult",
    "dnc_machine",
    "grbl_command",
    "halt_on_signals",
    "load_program",
    "parse_request",
    "parse_status",
    "prepare_send",
    "program_from_text",
    "protocol_of",
    "read_csv_record",
    "remote_server",
    "restart_blocks",
    "restart_plan",
    "serial_settings",
    "streamer_class",
]

"""What ``cutlab dnc send|serve`` set up from their options: the machine of a protocol, its serial
settings with the command's overrides, and a streamer ready to send a program (restart preamble
included) or a remote-request server.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rig.dnc.errors import DncError
from rig.dnc.fanuc import FanucStreamer
from rig.dnc.grbl import GrblStreamer
from rig.dnc.port import check_protocol, check_settings
from rig.dnc.program import Program, load_program
from rig.dnc.protocols import protocol_of
from rig.dnc.record import CsvSink, MemorySink
from rig.dnc.remote import RemoteServer
from rig.dnc.restart import RestartPlan, restart_plan
from rig.dnc.result import StreamResult

if TYPE_CHECKING:
    from analysis.config import MachineConfig, SerialConfig
    from rig.dnc._stream import Item

#: each protocol's streamer, by the protocol it speaks
STREAMERS: dict[str, type[FanucStreamer] | type[GrblStreamer]] = {
    cls.protocol: cls for cls in (FanucStreamer, GrblStreamer)
}


def streamer_class(protocol: str) -> type[FanucStreamer] | type[GrblStreamer]:
    """The streamer of ``protocol`` (a dialect without one: see :func:`protocol_of`)."""
    return STREAMERS[protocol_of(protocol).name]


def dnc_machine(protocol: str, name: str | None = None) -> tuple[str, MachineConfig]:
    """(checked protocol, machine): ``name`` (a config name or TOML path; None: the protocol's
    ``default_machine``) loaded and checked to speak ``protocol``."""
    from analysis.config import load_machine

    protocol = check_protocol(protocol)
    default = protocol_of(protocol).default_machine
    m = load_machine(name or default)
    if m.dialect != protocol:
        raise DncError(
            f"machine {m.name!r} has dialect = {m.dialect!r} but --protocol is {protocol!r}; "
            f"pick a {protocol} machine (e.g. --machine {default})"
        )
    return protocol, m


def serial_settings(
    machine: MachineConfig,
    port: str | None = None,
    baud: int | None = None,
    timeout_s: float | None = None,
) -> SerialConfig:
    """The machine's serial settings with a command's overrides (None: the machine's)."""
    from analysis.config import SerialConfig
    from analysis.validation import validate

    data: dict[str, Any] = machine.serial.model_dump()
    if port is not None:
        data["port"] = port
    if baud is not None:
        data["baudrate"] = baud
    if timeout_s is not None:
        data["timeout_s"] = timeout_s
    return validate(SerialConfig, data, f"machine {machine.name} serial (with command options)")


@dataclass(frozen=True)
class SendJob:
    """A program checked and a streamer set up to send it from ``start_block`` (after the
    restart ``preamble``, with the blocks a restart completes ``replaced``); :meth:`send`
    streams it."""

    protocol: str
    program: Program
    settings: SerialConfig
    streamer: FanucStreamer | GrblStreamer
    start_block: int
    preamble: list[str]
    replaced: dict[int, str] | None = None
    restart_notes: tuple[str, ...] = ()  # where the restart's clearance and plunge feed came from

    def items_to_send(self) -> list[Item]:
        """What :meth:`send` would send, as ``rig.dnc._stream.Item`` s (``block`` -1: the
        preamble): the preamble, then the program from ``start_block``, as the protocol sends
        them (GRBL: stripped unless ``--no-strip``, and checked against GRBL's parser). Nothing
        is opened."""
        from rig.dnc._stream import items_for

        items = items_for(self.program, self.start_block, self.preamble, self.replaced)
        return list(self.streamer._prepare(self.program, items))

    def send(self) -> StreamResult:
        """Stream the program; a fault raises :class:`~rig.dnc.errors.StreamFault`."""
        return self.streamer.send(
            self.program, self.start_block, self.preamble, replaced=self.replaced
        )


def prepare_send(
    file: str | Path,
    protocol: str,
    *,
    machine: str | None = None,
    port: str | None = None,
    baud: int | None = None,
    timeout_s: float | None = None,
    start_block: int = 0,
    safe_z_mm: float | None = None,
    plunge_feed_mm_min: float | None = None,
    record_csv: str | Path | None = None,
    progress: bool = False,
    grbl_mode: str = "char-counting",
    grbl_unlock: bool = False,
    grbl_strip: bool = True,
    fanuc_wait_dc1: bool = True,
    guard: bool = False,
) -> SendJob:
    """Everything ``cutlab dnc send`` checks before the port is opened: protocol, machine,
    serial settings, the program (NC errors raise here) and the restart preamble (arcs and
    canned cycles completed; ``safe_z_mm`` / ``plunge_feed_mm_min`` override the program's
    clearance and plunge feed); the block record goes to ``record_csv`` (None: kept in memory).
    ``guard``: GRBL, a watchdog process holds the feed if this process dies mid-stream."""
    protocol, m = dnc_machine(protocol, machine)
    cfg = serial_settings(m, port, baud, timeout_s)
    check_settings(cfg, protocol)
    program = load_program(file)
    plan: RestartPlan = restart_plan(
        program, start_block, protocol, m, safe_z_mm, plunge_feed_mm_min
    )
    sink = CsvSink(record_csv) if record_csv else MemorySink()
    kw: dict[str, Any]
    if protocol_of(protocol).paced_by_ok:  # ok pacing: its mode, $X unlock, stripping, watchdog
        kw = dict(mode=grbl_mode, unlock=grbl_unlock, strip=grbl_strip, guard=guard)
    else:  # drip feed: the control's DC1 starts the stream
        kw = dict(wait_for_dc1=fanuc_wait_dc1)
    st = streamer_class(protocol)(cfg, sink=sink, progress=progress, machine=m, **kw)
    return SendJob(protocol, program, cfg, st, start_block, plan.preamble, plan.replaced,
                   tuple(plan.notes))  # fmt: skip


def remote_server(
    machine: str | None = None,
    port: str | None = None,
    folder: str | Path | None = None,
    on_listening: Callable[[str, Path], None] | None = None,
) -> RemoteServer:
    """A :class:`~rig.dnc.remote.RemoteServer` on a Fanuc machine's port (``port`` overrides it);
    ``on_listening(port, folder)`` is called each time it waits for a request."""
    _, m = dnc_machine("fanuc", machine)
    cfg = serial_settings(m, port)
    srv = RemoteServer(cfg, folder, machine=m)
    if on_listening is not None:
        srv.on_listening = lambda: on_listening(cfg.port, srv.folder)
    return srv

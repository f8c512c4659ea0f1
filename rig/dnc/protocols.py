"""The streaming protocols: one :class:`StreamProtocol` per way bytes go down the wire to a control
(Fanuc drip feed, GRBL), holding every rule ``rig`` asks by name of the rule, never by the
protocol's name (tests/test_layers.py checks that nothing outside the registries compares it).

    from rig.dnc.protocols import protocol_of
    p = protocol_of("grbl")            # once, where the protocol is known
    p.realtime_bytes, p.done, p.dialect.cutter_comp, p.default_machine

A protocol streams one dialect (:attr:`StreamProtocol.dialect`, from ``planning.nc.dialects``,
whose ``Dialect.protocol`` names the protocol back). The streamer of a protocol is
:func:`rig.dnc.connect.streamer_class`, its simulated controller
:func:`rig.sim.controllers.controller_class` (each looked up by :attr:`StreamProtocol.name` where
the classes are imported, so rig.dnc never imports rig.sim). A new protocol is one
``StreamProtocol`` here, its entry in :data:`REGISTRY`, a streamer and a simulated controller.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from planning.nc.dialects import Dialect, get
from rig.dnc.errors import DncError

#: Baud rates a Fanuc reader/punch interface can be set to (parameter I/O channel baud codes).
FANUC_BAUDS = (50, 100, 110, 150, 200, 300, 600, 1200, 2400, 4800, 9600, 19200, 38400, 76800,
               86400, 115200)  # fmt: skip


@dataclass(frozen=True)
class StreamProtocol:
    """How ``rig.dnc`` streams to one kind of control (see the module docstring)."""

    name: str  # --protocol, the streamer's and the simulated controller's ``protocol``
    title: str  # how messages name the control: "GRBL"
    dialect_name: str  # the planning.nc dialect of the programs it streams
    default_machine: str  # the machine config used when none is named
    #: each line is answered ``ok`` / ``error:N`` and sent by character counting (GRBL); else the
    #: control paces the sender with DC1/DC3 (XON/XOFF) or RTS/CTS and answers nothing
    paced_by_ok: bool
    #: 8 data bits, no parity, 1 stop bit and no flow control only (else a tape reader's framing:
    #: 7 or 8 bits, any parity, 1 or 2 stop bits, a baud rate of :attr:`bauds`)
    serial_8n1_only: bool
    #: feed hold ``!``, cycle start ``~``, soft reset 0x18 and the overrides 0x90-0x9D go over
    #: the line (else the operator's buttons on the control's panel)
    realtime_bytes: bool
    #: ``?`` is answered with a status report, so the block executing is known (else predicted)
    status_query: bool
    #: the last block a fault message counts: "acknowledged" (answered) or "fully sent"
    done: str
    #: the streamer waits for the control's Idle after the last block, so the program's end is
    #: known (else the end is the stream's end plus the program's remaining machine time)
    end_known: bool
    #: words of a restart preamble the control refuses (left out), None: all sent
    preamble_drop: re.Pattern[str] | None = None
    #: the baud rates its interface can be set to (None: any the port takes)
    bauds: tuple[int, ...] | None = None

    @property
    def dialect(self) -> Dialect:
        """The dialect it streams (its interpretation, refusals and dwell units)."""
        return get(self.dialect_name)

    def takes_compensation(self, cutter_comp: int, tool_length: int) -> bool:
        """Whether a restart may restore cutter compensation ``cutter_comp`` (40, 41, 42) and
        tool length ``tool_length`` (43, 49): the dialect has G41/G42 and does not refuse G43."""
        d = self.dialect
        return (cutter_comp == 40 or d.cutter_comp) and (
            tool_length != 43 or 430 not in d.refused_g
        )


FANUC = StreamProtocol(
    name="fanuc",
    title="Fanuc",
    dialect_name="fanuc",
    default_machine="ace-h63",
    paced_by_ok=False,
    serial_8n1_only=False,
    realtime_bytes=False,
    status_query=False,
    done="fully sent",
    end_known=False,
    bauds=FANUC_BAUDS,
)
GRBL = StreamProtocol(
    name="grbl",
    title="GRBL",
    dialect_name="grbl",
    default_machine="lab-grbl",
    paced_by_ok=True,
    serial_8n1_only=True,
    realtime_bytes=True,
    status_query=True,
    done="acknowledged",
    end_known=True,
    # GRBL 1.1 answers error:20 to these (no return modes, absolute arc centres, tool change or
    # path mode there); the preamble's state holds without them
    preamble_drop=re.compile(r"\b(G98|G99|G90\.1|M6|G64(\s*[PQ]\s*[-+.\d]+)*)\b"),
)

#: name -> protocol, in the order of planning.nc.dialects.protocols()
REGISTRY: dict[str, StreamProtocol] = {p.name: p for p in (FANUC, GRBL)}
#: a machine whose dialect has no protocol (its control reads files: LinuxCNC, Mach3) is fed as
#: a tape reader, which is what a serial link to such a control can carry
FALLBACK = FANUC


def protocol_of(name: str | StreamProtocol) -> StreamProtocol:
    """The protocol called ``name`` (a protocol is returned as it is); a dialect without one
    (``linuxcnc``, ``mach3``) gets :data:`FALLBACK`; DncError for a name that is neither."""
    if isinstance(name, StreamProtocol):
        return name
    p = REGISTRY.get(name)
    if p is not None:
        return p
    try:
        own = get(name).protocol
    except ValueError:
        raise DncError(
            f"protocol = {name!r}: unknown; expected one of {', '.join(REGISTRY)}"
        ) from None
    return REGISTRY[own] if own is not None else FALLBACK


__all__ = ["FALLBACK", "FANUC", "FANUC_BAUDS", "GRBL", "REGISTRY", "StreamProtocol", "protocol_of"]

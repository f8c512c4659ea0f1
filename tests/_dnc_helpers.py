"""Shared by tests/test_dnc*.py: programs, serial settings and waits with a bound."""

from __future__ import annotations

import threading

from analysis.config import SerialConfig
from planning.nc.grbl import grbl_send_text
from rig.dnc import Program, program_from_text
from rig.dnc.grbl import HANDSHAKE
from rig.sim import SimClock, SimFanuc

FANUC_LINE_B_S = 115200 / 11  # 7E2
GRBL_LINE_B_S = 115200 / 10  # 8N1


def line_program(n: int, feed_mm_min: float = 6000.0, step_mm: float = 1.0, grbl: bool = False,
                 numbered: bool = False) -> Program:  # fmt: skip
    """A program of n 1 mm (step) zig-zag feed moves after a short header."""
    head = ["%", "O1234" if not grbl else "(cutlab test)", "G21 G90 G17 G54"]
    head += [] if grbl else ["T1 M6"]
    head += ["S3000 M3", "G0 X0 Y0 Z5", "G1 Z-1 F600"]
    body = [
        f"{f'N{i + 10} ' if numbered else ''}G1 X{(i + 1) * step_mm:.3f} Y{(i % 2) * 0.5:.3f} "
        f"F{feed_mm_min:g}"
        for i in range(n)
    ]
    tail = ["G0 Z50", "M5", "M30", "%"]
    return program_from_text("\n".join(head + body + tail) + "\n", "test.nc")


def fanuc_sim(speed: float, **kw: object) -> SimFanuc:
    """A simulated Fanuc at 115200 baud whose buffer leaves 4096 characters of room after its
    DC3: at x4 the line is 42 kB per wall second, so a streamer and controller sharing a loaded
    CPU may take up to ~100 ms to react without an (unwanted) overrun alarm. DC1 at 1024
    (``kw`` overrides these)."""
    params: dict = dict(rx_buffer_bytes=8192, xoff_free_bytes=4096, xon_fill_bytes=1024)
    return SimFanuc(clock=SimClock(speed), baudrate=115200, **(params | kw))


def fanuc_cfg(path: str, **kw: object) -> SerialConfig:
    d: dict = dict(port=path, baudrate=115200, bytesize=7, parity="E", stopbits=2,
                   flow_control="xonxoff", leader_nuls=10, timeout_s=5.0)  # fmt: skip
    d.update(kw)
    return SerialConfig(**d)


def grbl_cfg(path: str, **kw: object) -> SerialConfig:
    d: dict = dict(port=path, baudrate=115200, bytesize=8, parity="N", stopbits=1,
                   flow_control="none", xonxoff_in_streamer=False, timeout_s=5.0)  # fmt: skip
    d.update(kw)
    return SerialConfig(**d)


def fanuc_bytes(program: Program, cfg: SerialConfig, preamble: list[str] | None = None,
                start: int = 0) -> bytes:  # fmt: skip
    """What a drip feed of ``program`` puts on the wire."""
    eob = {"LF": b"\n", "CRLF": b"\r\n", "CR": b"\r"}[cfg.end_of_block]
    lead = b"\0" * cfg.leader_nuls
    blocks = [b.text for b in program.blocks if b.index >= start]
    body = b"".join(t.encode() + eob for t in (preamble or []) + blocks)
    return lead + b"%" + eob + body + b"%" + lead


def grbl_sent(texts: list[str], strip: bool = True) -> list[str]:
    """The lines a GRBL stream sends for ``texts`` (by default stripped of comments, spaces, N
    and lone O words; lines left empty are not sent)."""
    out = [grbl_send_text(t) if strip else t for t in texts]
    return [t for t in out if t]


def grbl_texts(program: Program, preamble: list[str] | None = None, start: int = 0,
               strip: bool = True) -> list[str]:  # fmt: skip
    """The lines a GRBL stream sends: ``preamble``, then the program from block ``start``."""
    blocks = [b.text for b in program.blocks if b.index >= start]
    return grbl_sent((preamble or []) + blocks, strip)


def grbl_bytes(program: Program, preamble: list[str] | None = None, start: int = 0,
               strip: bool = True) -> bytes:  # fmt: skip
    """What a GRBL stream puts on the wire (the handshake's "$G" first)."""
    texts = grbl_texts(program, preamble, start, strip)
    return HANDSHAKE + b"".join(t.encode() + b"\n" for t in texts)


class EventWaiter:
    """Controller listener: wait (bounded) for an event kind."""

    def __init__(self, ctl: object, kind: str) -> None:
        self.kind = kind
        self.hit = threading.Event()
        ctl.add_listener(on_event=self._on)  # type: ignore[attr-defined]

    def _on(self, ev: object) -> None:
        if ev.kind == self.kind:  # type: ignore[attr-defined]
            self.hit.set()

    def wait(self, timeout_s: float = 60.0) -> bool:
        return self.hit.wait(timeout_s)


#: full and incremental arcs, modal G2/G3 and a G91 stretch: what a restart must make complete
ARCS = """G21 G90 G17
S1000 M3
G0 X0 Y0 Z5
G1 Z-1 F300
G1 X10
G2 X20 Y0 I5 J0
X30 I5
G91 G3 X-10 Y0 I-5
X-10 I-5
G90 G1 X0 Y0
G0 Z5
M5
M30
"""

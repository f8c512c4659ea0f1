"""Remote program request, as shop DNC servers offer it.

At the control the operator punches (sends) a short request program; the control frames its
output with DC2 ... DC4. The request names a program and may name a start block::

    %
    O9999 (PRG=1234) (BLK=120)
    %

:class:`RemoteServer` listens on the port, reads the request, finds the program in the configured
folder (``serial.program_folder``; tried as ``NAME``, ``NAME.nc``, ``ONAME``, ``ONAME.nc``, any
case), checks it, and drip-feeds it when the control asks (DC1), with the restart preamble when a
start block is named (:mod:`rig.dnc.restart`).
"""

from __future__ import annotations

import re
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from analysis.config import MachineConfig, SerialConfig
from rig.dnc.errors import DncError
from rig.dnc.fanuc import FanucStreamer
from rig.dnc.program import Program, load_program
from rig.dnc.record import BlockSink
from rig.dnc.restart import restart_plan
from rig.dnc.result import StreamResult

_PRG = re.compile(r"\(\s*PRG\s*=\s*([A-Za-z0-9_.\-]+)\s*\)", re.IGNORECASE)
_BLK = re.compile(r"\(\s*(?:BLK|START)\s*=\s*(\d+)\s*\)", re.IGNORECASE)


@dataclass(frozen=True)
class Request:
    """A parsed remote request: program name and start block (0 = from the start)."""

    program: str
    start_block: int = 0


def parse_request(text: str) -> Request:
    """``O9999 (PRG=1234) (BLK=120)`` -> Request('1234', 120); DncError if no PRG= is named."""
    m = _PRG.search(text)
    if m is None:
        raise DncError(
            f"remote request {text.strip()!r}: names no program; expected e.g. "
            "'O9999 (PRG=1234)' with an optional '(BLK=120)'"
        )
    b = _BLK.search(text)
    return Request(m.group(1), int(b.group(1)) if b else 0)


def find_program(folder: str | Path, name: str) -> Path:
    """The file in ``folder`` serving program ``name``."""
    d = Path(folder)
    if not d.is_dir():
        raise DncError(f"serial.program_folder = {str(folder)!r}: not a folder")
    want = {name.lower(), f"{name}.nc".lower(), f"o{name}".lower(), f"o{name}.nc".lower()}
    for p in sorted(d.iterdir()):
        if p.is_file() and p.name.lower() in want:
            return p
    raise DncError(
        f"remote request for program {name!r}: not in {d} (looked for {name}, {name}.nc, "
        f"O{name}, O{name}.nc)"
    )


class RemoteServer:
    """Answer one remote request at a time on a Fanuc-style link."""

    def __init__(
        self,
        cfg: SerialConfig,
        folder: str | Path | None = None,
        *,
        machine: MachineConfig | None = None,
        sink: BlockSink | None = None,
        pace_bytes_per_s: float | Literal["auto"] | None = "auto",
        on_listening: Callable[[], None] | None = None,
    ) -> None:
        self.cfg = cfg
        self.folder = Path(folder or cfg.program_folder or ".")
        self.machine = machine
        self.streamer = FanucStreamer(cfg, sink=sink, pace_bytes_per_s=pace_bytes_per_s)
        self.request: Request | None = None
        self.program: Program | None = None
        #: set once the port is open and a request can be received
        self.listening = threading.Event()
        self.on_listening = on_listening

    def serve_one(self, wait_s: float | None = None) -> StreamResult:
        """Wait for a request (``wait_s`` None: forever), then send what it names."""
        st = self.streamer
        link = st._open()
        try:
            done = threading.Event()
            punched: list[bytes] = []

            def on_control(b: int) -> None:
                st._on_control(b)
                if not st.punching.is_set() and st.punched:
                    punched.append(bytes(st.punched))
                    st.punched.clear()
                    done.set()

            link.on_control = on_control  # the streamer's, plus: a finished request ends the wait
            self.listening.set()
            if self.on_listening is not None:
                self.on_listening()
            while not done.wait(0.05):
                if link.lost.is_set():
                    raise DncError(f"remote request: port lost ({link.lost_reason})")
                if wait_s is not None:
                    wait_s -= 0.05
                    if wait_s <= 0:
                        raise DncError("remote request: none received in time")
            self.request = parse_request(punched[0].decode("ascii", "replace"))
            path = find_program(self.folder, self.request.program)
            self.program = load_program(path)
            plan = restart_plan(self.program, self.request.start_block, "fanuc", self.machine)
            link.dc1_seen.clear()  # wait for the control to start reading again
            return st.send(
                self.program, self.request.start_block, plan.preamble, link=link,
                replaced=plan.replaced,
            )  # fmt: skip
        finally:
            self.listening.clear()
            link.close()

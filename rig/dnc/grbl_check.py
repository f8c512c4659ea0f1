"""Before the first byte of a GRBL stream: what a line sent to it may hold (its buffers), and the
whole program checked against GRBL 1.1h (nothing is sent if any line would be refused)."""

from __future__ import annotations

from typing import Any

from planning.nc.dialect import check_dialect, refused
from planning.nc.grbl import GRBL_ERRORS, GrblParser, grbl_filter, grbl_send_text
from rig.dnc._stream import Item
from rig.dnc.errors import DncError
from rig.dnc.program import Program

GRBL_RX_BUFFER_BYTES = 127  # of RX_BUFFER_SIZE 128: one byte of margin
GRBL_LINE_CHARS = 79  # LINE_BUFFER_SIZE 80 incl. the terminating NUL
TRANSFORM = "stripped comments, spaces, N words and lone O program numbers"


def check_line(text: str, where: str, rx_buffer_bytes: int) -> None:
    """Raise DncError if GRBL cannot take this line (too long for its buffers)."""
    if len(text) + 1 > rx_buffer_bytes:
        raise DncError(
            f"{where}: line is {len(text) + 1} bytes with its LF; GRBL's receive buffer holds "
            f"{rx_buffer_bytes} (expected <= {rx_buffer_bytes} bytes)"
        )
    f = grbl_filter(text, limit=10**9)
    if len(f.text) > GRBL_LINE_CHARS:
        raise DncError(
            f"{where}: {len(f.text)} characters without spaces and comments; GRBL's line "
            f"buffer holds {GRBL_LINE_CHARS} (error:11)"
        )


def prepare_lines(
    program: Program, items: list[Item], *, strip: bool, rx_buffer_bytes: int
) -> tuple[list[Item], list[Any], int, list[str]]:
    """The lines as they will be sent (``strip``: as :func:`planning.nc.grbl.grbl_send_text`
    leaves them), GRBL's parse of each (None for a ``$`` line or one it refuses), the bytes
    stripped, and every line GRBL 1.1h would refuse (the whole program checked as
    :func:`planning.nc.dialect.check_dialect` does, then each line as sent)."""
    out: list[Item] = []
    stripped = 0
    for it in items:
        sent = grbl_send_text(it.text) if strip else it.text.strip()
        stripped += len(it.text) - len(sent)
        if sent:
            out.append(Item(it.block, it.line, sent, it.source or it.text))
    problems = refused(check_dialect(program.text, "grbl", file=program.name, strip=strip))
    listed = {p.line for p in problems}
    lines: list[str] = [str(p) for p in problems]
    parser = GrblParser()
    results: list[Any] = []
    for k, it in enumerate(out):
        where = f"{program.name}:{it.line}"
        if it.block < 0:
            where = f"restart preamble line {k + 1}"
        if len(it.text) + 1 > rx_buffer_bytes and (it.line not in listed or it.block < 0):
            lines.append(
                f"{where}: {len(it.text) + 1} bytes with its LF: more than the "
                f"{rx_buffer_bytes} bytes GRBL's receive buffer may hold"
            )
        if it.text.startswith("$"):
            results.append(None)
            continue
        f = grbl_filter(it.text)
        if f.overflow:
            if it.line not in listed or it.block < 0:
                n = len(grbl_filter(it.text, 10**9).text)
                lines.append(
                    f"{where}: GRBL error:11: line overflow: {n} characters without spaces "
                    f"and comments; GRBL's line buffer holds {GRBL_LINE_CHARS}"
                )
            results.append(None)
            continue
        res = parser.parse(f.text)
        results.append(res if res.ok else None)
        if not res.ok and (it.line not in listed or it.block < 0):
            lines.append(
                f"{where}: {res.word}: GRBL error:{res.code} "
                f"{GRBL_ERRORS.get(res.code, '')} (as sent: {it.text})"
            )
    return out, results, stripped, lines

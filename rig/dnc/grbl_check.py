"""GRBL 1.1's buffers: what a line sent to it may hold."""

from __future__ import annotations

from planning.nc.grbl import grbl_filter
from rig.dnc.errors import DncError

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

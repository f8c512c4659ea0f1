"""Who writes a run file: stored in a new run's status so that a reader can tell a live writer
from a dead one (:func:`analysis.runs.file.writer_alive`)."""

from __future__ import annotations

import os
import socket
from typing import TypedDict

__all__ = ["WriterIdentity", "writer_identity"]


class WriterIdentity(TypedDict):
    """The process writing a run file: its pid and host name."""

    pid: int
    host: str


def writer_identity() -> WriterIdentity:
    """The writing process (pid, host), stored in a new run's status so that a reader can tell a
    live writer from a dead one."""
    return {"pid": os.getpid(), "host": socket.gethostname()}

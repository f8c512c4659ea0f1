"""Errors of the DNC link: bad settings or program (before sending) and faults while streaming."""

from __future__ import annotations

from typing import TYPE_CHECKING

from rig.errors import RigError

if TYPE_CHECKING:
    from rig.dnc.result import StreamResult


class DncError(RigError):
    """A DNC input cannot be used: unknown protocol, missing port, settings the controller cannot
    take, or a program with an NC error. Raised before anything is sent."""


class StreamFault(DncError):
    """Streaming stopped part-way: the port disappeared, the controller stopped answering, an
    overrun, ``error:N``, an alarm, a reset, a lost answer, or the operator.

    ``result`` is the summary up to the fault (``result.last_acknowledged_block`` is the block to
    resume after, ``result.reason`` says why); the record sink has been closed before raising.
    ``kind`` is one of ``"port-lost"``, ``"timeout"``, ``"error"``, ``"alarm"``, ``"stopped"``,
    ``"interrupted"`` (Ctrl-C, SIGTERM, SIGHUP: held and reset first), ``"reset"`` (GRBL reset
    itself mid-stream), ``"lost-ok"`` (GRBL processed every line but an answer never came).
    """

    def __init__(self, message: str, kind: str, result: StreamResult) -> None:
        super().__init__(message)
        self.kind = kind
        self.result = result

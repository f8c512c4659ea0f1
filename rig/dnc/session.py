"""A send under the operator's control, as ``cutlab dnc send`` runs it: keys and SIGUSR1/SIGUSR2
hold and resume (:mod:`rig.dnc.keys`), Ctrl-C and SIGTERM halt cleanly (:mod:`rig.dnc.guard`),
and an optional loop beside the stream (the adaptive feed / spindle control,
``rig.adaptive.send.SendLoop``, which this package cannot import: it is passed in started)."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Mapping
from contextlib import AbstractContextManager
from dataclasses import dataclass
from typing import Any, Protocol

from rig.dnc.connect import SendJob
from rig.dnc.errors import StreamFault
from rig.dnc.guard import halt_on_signals
from rig.dnc.keys import operator_control
from rig.dnc.result import StreamResult, StreamSummary

__all__ = ["SendJson", "SendOutcome", "send_under_control"]


class RunningLoop(Protocol):
    """What a loop beside the stream gives once it has closed: its summary (JSON-ready)."""

    @property
    def summary(self) -> Mapping[str, object]: ...


class SendJson(StreamSummary, total=False):
    """`cutlab dnc send --json`: the stream's result, then the operator's actions and, with
    ``--adaptive``, the loop's summary."""

    operator_actions: list[dict[str, object]]
    adaptive: Mapping[str, object]


@dataclass
class SendOutcome:
    """What a send did: the stream's result, the operator's actions, the loop's summary."""

    result: StreamResult
    operator_actions: list[dict[str, Any]]
    adaptive: Mapping[str, object] | None = None

    def as_dict(self) -> SendJson:
        """``dnc send --json``: the result, then ``operator_actions`` (and ``adaptive``)."""
        # mypy looks for the optional "adaptive" in the ** item; it is set below when there is one
        out: SendJson = {**self.result.as_dict(), "operator_actions": self.operator_actions}  # type: ignore[typeddict-item]
        if self.adaptive is not None:
            out["adaptive"] = self.adaptive
        return out


def send_under_control(
    job: SendJob,
    loop: AbstractContextManager[RunningLoop] | None = None,
    on_fault: Callable[[SendOutcome], None] | None = None,
) -> SendOutcome:
    """Stream ``job`` with the operator's keys and signals live; ``loop`` (its value has a
    ``summary``, read once it has closed) runs beside the stream. On a fault ``on_fault`` gets
    what was sent and done (no loop summary), then the :class:`StreamFault` propagates."""
    with (
        operator_control(job.streamer, job.protocol) as ctl,
        loop if loop is not None else contextlib.nullcontext(None) as running,
    ):
        try:
            with halt_on_signals(job.streamer, on_signal=ctl.note):  # Ctrl-C: hold, clean halt
                res = job.send()
        except StreamFault as exc:
            ctl.close()
            if on_fault is not None:
                on_fault(SendOutcome(exc.result, ctl.actions))
            raise
        ctl.close()
    return SendOutcome(res, ctl.actions, running.summary if running is not None else None)

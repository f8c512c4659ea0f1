"""The campaign's rig session seen by the console: the DAQ sink teed (the run's writer first,
then the live ring), the runner's holds, resumes and stops as events, and the machine as its
controller reports it. ``live`` is the campaign's :class:`rig.console.live.LiveCampaign` (not
imported: it imports this)."""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from analysis.runs import file as rf
from rig.console.program_path import _round
from rig.console.results import MachineReport
from rig.daq import DaqEvent, DaqInfo


class LiveSink(Protocol):
    """What the console needs beside the run writer: the DAQ sink calls, plus runner events.
    (Wired today by teeing the DAQ sink; ``RunWriter`` may call it directly later.)"""

    def on_start(self, info: DaqInfo, t0_s: float) -> None: ...

    def on_block(self, first_sample: int, data: np.ndarray) -> None: ...

    def on_event(self, event: DaqEvent) -> None: ...

    def note(self, kind: str, message: str, time_s: float | None = None) -> None: ...


class _Tee:
    """The DAQ sink given to the DAQ: the run's own sink first, then the live ring (which has
    the block already when the run writer's buffers are its slots)."""

    def __init__(self, sink: Any, live: Any) -> None:
        self.sink, self.live = sink, live

    def on_start(self, info: DaqInfo, t0_s: float) -> None:
        self.sink.on_start(info, t0_s)
        self.live.guard(self.live.on_start, info, t0_s)
        self.live.guard(self.live.share_with, self.sink)  # the writer's copy feeds the ring

    def on_block(self, first_sample: int, data: np.ndarray) -> None:
        self.sink.on_block(first_sample, data)
        try:  # guard() inlined: this runs once per block on the acquisition thread
            self.live.on_block(first_sample, data)
        except Exception:  # noqa: BLE001 - the live view must never endanger the recording
            self.live.tap_errors += 1

    def on_event(self, event: DaqEvent) -> None:
        self.sink.on_event(event)
        self.live.guard(self.live.on_event, event)


class _LiveDaq:
    def __init__(self, daq: Any, live: Any) -> None:
        self._daq, self._live = daq, live

    def start(self, sink: Any) -> None:
        self._daq.start(_Tee(sink, self._live))

    def __getattr__(self, name: str) -> Any:
        return getattr(self._daq, name)


class _LiveSession:
    """A rig session seen by the console: the runner's calls pass through; the runner's own
    holds, resumes and stops become events."""

    def __init__(self, inner: Any, live: Any) -> None:
        self.inner = inner
        self.daq = _LiveDaq(inner.daq, live)
        self.clock = inner.clock
        self.writer: Any = None
        self.program: Any = None
        self._live = live

    def start(self, program: Any, writer: object) -> None:
        self.program, self.writer = program, writer
        self._live.guard(self._live.on_program, program)
        self.inner.start(program, writer)

    def feed_hold(self) -> None:
        self.inner.feed_hold()
        self._live._held = True
        self._live.note(rf.EV_PAUSE, "runner: feed hold")

    def cycle_start(self) -> None:
        self.inner.cycle_start()
        self._live._held = False
        self._live.note(rf.EV_RESUME, "runner: cycle start")

    def stop(self) -> None:
        self.inner.stop()
        self._live.note("abort", "runner: stop (feed hold, reset)")

    def close(self) -> None:
        try:
            self.inner.close()
        finally:
            self._live.on_session_closed(self)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


def machine_report(session: object) -> MachineReport:
    """The machine as its controller reports it: GRBL's last status report; the simulated
    control's panel; nothing from a drip feed (state "" and source says so)."""
    streamer = getattr(session, "streamer", None)
    st = getattr(streamer, "last_status", None)
    out: MachineReport = {"state": "", "pos_mm": None, "feed_mm_min": None, "spindle_rpm": None}
    if st is not None:
        pos = st.wpos_mm
        wco = getattr(streamer, "_wco", None)
        if pos is None and st.mpos_mm is not None:
            off = wco if wco is not None else (0.0, 0.0, 0.0)
            pos = tuple(m - o for m, o in zip(st.mpos_mm, off))
        ov = getattr(st, "overrides", None)
        overrides = dict(zip(("feed", "rapid", "spindle"), ov)) if ov else None
        out.update({"state": st.full_state, "pos_mm": _round(pos), "source": "GRBL status",
                    "feed_mm_min": st.feed_mm_min, "spindle_rpm": st.spindle_rpm,
                    "overrides_pct": overrides, "estimated": False})  # fmt: skip
        return out
    ctrl = getattr(session, "controller", None)  # the simulated rig's control
    if ctrl is not None:
        if hasattr(ctrl, "state_name"):
            state = ctrl.state_name()
        else:
            state = "Alarm" if ctrl.alarm else "Hold" if ctrl.held else "Run"
        pos = ctrl.position_mm() if hasattr(ctrl, "position_mm") else None
        out.update({"state": state, "pos_mm": _round(pos), "source": "simulated control"})
        return out
    state = getattr(streamer, "controller_state", "") or ""
    out.update({"state": state, "source": "none: a drip feed reports no state"})
    return out

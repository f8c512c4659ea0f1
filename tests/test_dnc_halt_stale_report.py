"""A halt resets GRBL only once a report made after the feed hold says it has stopped.

A status report that left GRBL before its ``!`` arrived can reach the streamer after the ``!``
went out (a ``?`` of the status poller in flight). GRBL 1.1h answers ``!`` with Hold from Idle too
(protocol.c: "If IDLE, Grbl is not in motion. Simply indicate suspend state and hold is
complete", then ``sys.state = STATE_HOLD``), so an ``Idle`` read right after the hold may be such
a report from before it: a soft reset on it can hit a decelerating machine (mc_reset: ALARM:3).
The simulated GRBL over a real pty below sends one such report just as the hold reaches it.
"""

from __future__ import annotations

import threading

from _dnc_helpers import grbl_cfg

from rig.dnc import GrblStreamer, MemorySink, StreamFault, program_from_text
from rig.sim import SimClock, SimGrbl


class _ReportInFlight(SimGrbl):
    """The simulated GRBL, with an ``Idle`` report from before the feed hold on the wire just
    as the hold arrives (the answer to a '?' sent before the '!')."""

    def _on_bytes(self, data: bytes, t: float) -> None:
        if b"!" in data and self._moving():
            self.stale_sent = getattr(self, "stale_sent", 0) + 1
            self._reply(b"<Idle|MPos:0.000,0.000,0.000|FS:0,0>\r\n")
        super()._on_bytes(data, t)


def test_a_report_from_before_the_hold_does_not_release_the_reset() -> None:
    lines = ["G21 G90 G17 G54", "S10000 M3", "G0 X0 Y0 Z5", "G1 Z-1 F600"]
    lines += [f"G1 X{10 * (k % 2 + 1)} Y{k} F300" for k in range(40)] + ["G0 Z5", "M5", "M30"]
    prog = program_from_text("\n".join(lines) + "\n", "long.nc")
    ctl = _ReportInFlight(clock=SimClock(1.0), status_report_mask=3)
    with ctl:
        st = GrblStreamer(grbl_cfg(ctl.path, timeout_s=5.0), clock=ctl.clock.now,
                          sink=MemorySink(), status_hz=5.0)  # fmt: skip
        # stop in the middle of a 10 mm move at F300 (2 s): decelerating when the reset could come
        timer = threading.Timer(1.5, st.stop)
        timer.start()
        try:
            res = st.send(prog)
        except StreamFault as exc:
            res = exc
        finally:
            timer.cancel()
    assert isinstance(res, StreamFault) and res.kind == "stopped", res
    assert getattr(ctl, "stale_sent", 0) >= 1, "the hold reached a moving GRBL"
    kinds = [e.kind for e in ctl.events]
    assert "hold_request" in kinds and "reset" in kinds, kinds
    assert ctl.alarm == "" and "alarm" not in kinds, [(e.kind, e.detail) for e in ctl.events]

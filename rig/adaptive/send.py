"""``dnc send --adaptive``: the loop around a GRBL stream outside a campaign. The force comes
from the rig's DAQ (configs/rig.toml's NI device, or a given one), opened in this process for
the send: zeroed on its first ``rest_s`` (the spindle must be still when the send starts), every
block to the controller, the overrides through the send's streamer. No run file is written
(record with a campaign for that): the decisions go to stderr, the figures to the summary.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, cast

from rig.adaptive.controller import AdaptiveController
from rig.adaptive.results import AdaptiveSummary
from rig.adaptive.session import _Tee
from rig.adaptive.settings import AdaptiveSettings
from rig.dnc import DncError, protocol_of

if TYPE_CHECKING:
    from rig.daq import Daq
    from rig.dnc import SendJob
    from rig.dnc.grbl import GrblStreamer

#: wall s the DAQ may take to deliver the zeroing rest before the send is refused
ZERO_WAIT_S = 10.0


class _Null:
    def on_start(self, info: Any, t0_s: float) -> None: ...

    def on_block(self, first_sample: int, data: Any) -> None: ...

    def on_event(self, event: Any) -> None: ...


class _Printer:
    """The controller's events as stderr lines (no run file in a plain send)."""

    def __init__(self, say: Any) -> None:
        self.say = say

    def event(self, kind: str, message: str = "", *, time_s: float | None = None, **_: Any) -> None:
        self.say(f"{message} ({kind})")


class SendLoop:
    """A context around ``job.send()``: the DAQ started and zeroed, the controller armed on
    ``job.streamer``; on exit the DAQ stopped and closed. ``daq`` default: the NI DAQ of
    ``rig`` (a path, default configs/rig.toml)."""

    def __init__(
        self, job: SendJob, settings: AdaptiveSettings, spindle_rpm: float, *,
        rig: str | None = None, daq: Daq | None = None, rest_s: float = 0.2,
        say: Callable[[str], None] | None = None,
    ) -> None:  # fmt: skip
        from analysis.config import load_rig
        from rig.daq.calibration import Calibration

        if not protocol_of(getattr(job, "protocol", "grbl")).realtime_bytes:
            raise DncError(f"--adaptive: the {job.protocol} controller has no real-time override")
        rig_cfg = load_rig(rig) if rig else load_rig()
        if daq is None:
            from rig.daq.ni import NiDaq

            daq = NiDaq.from_rig(rig_cfg, where=rig or "configs/rig.toml")
        self.daq = daq
        self.job = job
        self.cal = Calibration.from_dynamometer(rig_cfg.dynamometer)
        self.ctl = AdaptiveController(
            settings, spindle_rpm=spindle_rpm, channels=tuple(self.cal.channel_names),
            clock=time.monotonic, writer=_Printer(say) if say else None,
        )  # fmt: skip
        self.ctl.stamp_arrival = True  # the DAQ's clock is not this process's monotonic one
        self.zero_samples = max(2, int(round(rest_s * daq.info.rate_hz)))
        self.drop_after_s = None

    def __enter__(self) -> SendLoop:
        return self.start()

    def start(self) -> SendLoop:
        """Start the DAQ and wait for the zero (idempotent); the controller armed."""
        if self.ctl.streamer is not None:
            return self
        self.daq.start(_Tee(_Null(), self))
        deadline = time.monotonic() + ZERO_WAIT_S
        while self.ctl.force_of is None:
            if time.monotonic() > deadline or self.daq.done:
                self.daq.stop()
                raise DncError(f"--adaptive: no rest samples from the DAQ within {ZERO_WAIT_S:g} "
                               "s: nothing sent")  # fmt: skip
            time.sleep(0.01)
        # __init__ refused a protocol without real-time bytes: the streamer is GRBL's
        self.ctl.attach(cast("GrblStreamer", self.job.streamer))
        self.ctl.arm()
        return self

    def __exit__(self, *exc: object) -> None:
        self.ctl.close()
        self.daq.stop()
        close = getattr(self.daq, "close", None)
        if close is not None:
            close()

    @property
    def summary(self) -> AdaptiveSummary:
        return self.ctl.summary()

"""The real rig behind the campaign's :class:`RigSession`: the NI DAQ of ``configs/rig.toml`` and
the machine's serial port (``[serial]`` of the machine config) with the DNC streamer.

What differs from the simulated rig, and what the operator does (see the README's lab procedure):

- GRBL: feed hold ``!``, cycle start ``~`` and soft reset go over the link; the streamer waits
  for ``Idle`` after the last block, so the end of the program is known.
- Fanuc drip feed has no acknowledgement and no remote feed hold: the control executes what it
  has read. The run ends when the stream has ended and the program's remaining machine time
  (from ``planning.nc``) has passed, plus a margin; a pause or stop asks the operator to press
  FEED HOLD / RESET on the panel, and the streamer stops sending.
- The door interlock is the machine's own; an interlock trip shows up as a controller alarm or a
  stream timeout and ends the run with its reason.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import TYPE_CHECKING, Any

from rig.dnc import DncError, Program, StreamFault, protocol_of
from rig.dnc.sinks import LoggerSink
from rig.errors import RigError

if TYPE_CHECKING:
    from rig.campaign.config import Campaign
    from rig.campaign.plan import PlannedRun

#: Seconds added to a Fanuc program's estimated remaining time before the run is taken as done.
FANUC_END_MARGIN_S = 3.0


def _daq_config(campaign: Campaign) -> Any:
    over = {
        k: v
        for k, v in campaign.spec.daq.model_dump().items()
        if v is not None and k in type(campaign.rig.daq).model_fields
    }
    return campaign.rig.daq.model_copy(update=over)


def check_hardware(campaign: Campaign) -> tuple[list[str], list[str]]:
    """(what was found, what is missing and how to fix it) for ``rig = "real"``. Opens the
    serial port and lists NI devices; sends nothing."""
    from rig.daq.ni import HOW_TO_CONFIGURE

    found: list[str] = []
    problems: list[str] = []
    daq = _daq_config(campaign)
    try:
        import nidaqmx

        devices = {d.name: d for d in nidaqmx.system.System.local().devices}
        names = list(devices)
    except Exception as exc:  # noqa: BLE001 - the driver-not-found error is not a DaqError
        problems.append(f"DAQ: NI-DAQmx driver not available ({type(exc).__name__}: {exc}). "
                        f"{HOW_TO_CONFIGURE}")  # fmt: skip
    else:
        if daq.device in names:
            found.append(f"DAQ device {daq.device} ({', '.join(daq.channels)})")
            dev = devices[daq.device]
            try:  # the device's own limit for this many channels, Hz per channel
                top = float(dev.ai_max_multi_chan_rate if len(daq.channels) > 1
                            else dev.ai_max_single_chan_rate)  # fmt: skip
            except Exception:  # noqa: BLE001 - a device that does not say
                top = float("inf")
            if daq.rate_hz > top:
                problems.append(f"DAQ: rate_hz = {daq.rate_hz:g} is above device {daq.device}'s "
                                f"limit {top:g} Hz per channel for {len(daq.channels)} channels")
        else:
            problems.append(
                f"DAQ: device {daq.device!r} (configs/rig.toml [daq] device) not found; present: "
                f"{', '.join(names) or 'none'}. {HOW_TO_CONFIGURE}"
            )
    cfg = campaign.machine.serial
    protocol = campaign.machine.dialect
    try:
        from rig.dnc.port import open_port

        port = open_port(cfg, protocol)
        port.close()
        found.append(f"serial port {cfg.port} ({cfg.baudrate} baud, {protocol})")
    except (DncError, RigError, OSError) as exc:
        problems.append(
            f"serial: {exc} (machine '{campaign.machine.name}' [serial] port = {cfg.port!r}; "
            "set it to the adapter's device, e.g. /dev/ttyUSB0 or COM3)"
        )
    return found, problems


class RealSession:
    """One run on the lab's rig (see the module docstring)."""

    def __init__(self, campaign: Campaign, plan: PlannedRun, run_index: int) -> None:
        from rig.daq.ni import NiDaq

        self.campaign = campaign
        self.protocol = campaign.machine.dialect
        self.rules = protocol_of(self.protocol)  # asked once: streamer, end, feed hold
        self.clock = time.monotonic
        names = [ch.name for ch in campaign.rig.dynamometer.channels]
        self.daq = NiDaq(_daq_config(campaign), names, clock=self.clock)
        self.expected_s = plan.expected_s
        self._fault: str | None = None
        self._done = threading.Event()
        self._t_stream_end: float | None = None
        self._program: Program | None = None
        self.streamer: Any = None

    def start(self, program: Program, writer: object) -> None:
        from rig.dnc import streamer_class

        self._program = program
        cls = streamer_class(self.rules.name)
        self.streamer = cls(self.campaign.machine.serial, sink=LoggerSink(writer),
                            clock=self.clock)  # fmt: skip
        t0 = self.clock()

        def stream() -> None:
            try:
                self.streamer.send(program)
            except StreamFault as exc:
                self._fault = f"DNC stream fault ({exc.kind}): {exc}"
            except (DncError, RigError, OSError) as exc:
                self._fault = f"DNC: {exc}"
            finally:
                self._t_stream_end = self.clock()
                self._stream_s = self._t_stream_end - t0
                self._done.set()

        threading.Thread(target=stream, name="dnc-stream", daemon=True).start()
        self._t_start = t0

    def finished(self) -> bool:
        if self._fault is not None:
            return True
        if not self._done.is_set():
            return False
        if self.rules.end_known:
            return True  # the streamer waited for Idle
        return self.clock() >= self._t_start + self.expected_s + FANUC_END_MARGIN_S

    def fault(self) -> str | None:
        return self._fault

    def progress(self) -> tuple[int, int]:
        n = len(self._program.blocks) if self._program is not None else 0
        sent = getattr(self.streamer, "blocks_sent", 0) if self.streamer is not None else 0
        return min(sent, n), n

    def executed_blocks(self) -> list[tuple[int, float, float, str]]:
        """Blocks known to have started executing (GRBL: from its status reports; Fanuc:
        predicted from the buffer and the time model), as the streamer tracks them."""
        return self.streamer.executed_blocks() if self.streamer is not None else []

    def feed_hold(self) -> None:
        if self.rules.realtime_bytes and self.streamer is not None:
            self.streamer.feed_hold()
        else:
            print("cutlab: press FEED HOLD on the control now", file=sys.stderr, flush=True)

    def cycle_start(self) -> None:
        if self.rules.realtime_bytes and self.streamer is not None:
            self.streamer.cycle_start()
        else:
            print("cutlab: press CYCLE START on the control", file=sys.stderr, flush=True)

    def stop(self) -> None:
        if self.streamer is None:
            return
        if not self.rules.realtime_bytes:
            print("cutlab: press RESET on the control (spindle stop)", file=sys.stderr, flush=True)
        self.streamer.stop()  # GRBL: feed hold, wait for Hold:0, then soft reset (no ALARM:3)

    def close(self) -> None:
        if self.streamer is not None and not self._done.is_set():
            self.streamer.stop()
            self._done.wait(timeout=self.campaign.machine.serial.timeout_s + 5)
        self.daq.close()


def real_session(campaign: Campaign, plan: PlannedRun, run_index: int) -> RealSession:
    """The campaign runner's session factory for ``rig = "real"``."""
    return RealSession(campaign, plan, run_index)

"""The simulated rig: a simulated controller on a pseudo-terminal, the simulated machine and the
simulated DAQ, all on one :class:`SimClock`, behind the campaign's :class:`RigSession` interface.

For each run: a new clock (``[sim] speed`` times real time), a new stock (the test block; a
``planning.stock.zmap.ZMap`` for end mills), the machine listening to the controller's executed
segments, a :class:`rig.daq.SimDaq` reading the machine's volts, and the real DNC streamer
(``rig.dnc``) opening the controller's tty through pyserial, exactly as on the lab's RS-232 link.

Notes
-----
How the simulated rig differs from the lab (beyond :mod:`rig.sim.machine`'s list):

- The serial link is a pty; its timeout is ``[sim] link_timeout_s`` instead of the machine's, so
  a hung controller is noticed within seconds of wall time.
- The door interlock exists only as the ``sim_interlock_at_s`` knob: at that simulated time the
  controller is held and reset (door opened: feed hold, spindle stop).
- Feed hold and cycle start go straight to the simulated controller (the operator's buttons);
  on a real Fanuc drip feed they are the operator's.
"""

from __future__ import annotations

import math
import threading
from typing import TYPE_CHECKING, Any

from analysis.forces.models import ENDMILL
from rig.dnc import DncError, Program, StreamFault, protocol_of
from rig.dnc.sinks import LoggerSink
from rig.errors import RigError
from rig.sim.campaign_view import SimCampaign, SimPlan
from rig.sim.clock import SimClock
from rig.sim.daq import SimDaq
from rig.sim.machine import BlockStock, SignalSettings, SimMachine, ZMapStock

if TYPE_CHECKING:
    import numpy as np

    from rig.sim.fanuc import SimFanuc
    from rig.sim.grbl import SimGrbl


def _make_stock(campaign: SimCampaign, plan: SimPlan) -> BlockStock | ZMapStock:
    tool = campaign.tool
    if not ENDMILL.describes(tool):
        return BlockStock(plan.cut.block)
    return ZMapStock(plan.cut.block.to_zmap(tool), tool)


class SimSession:
    """One run on the simulated rig (see the module docstring)."""

    def __init__(self, campaign: SimCampaign, plan: SimPlan, run_index: int) -> None:
        sim = campaign.spec.sim
        rig = campaign.rig
        self.protocol = sim.protocol or campaign.machine.dialect
        self.rules = protocol_of(self.protocol)  # asked once: which streamer and controller
        # Nothing moves in simulated time before the run arms it (:meth:`arm`): the DAQ's first
        # sample is at t = 0 however long the host took to get there.
        self.sim_clock = SimClock(sim.speed, gates={"arm": 0.0})
        self.clock = self.sim_clock.now
        self.simulated = True
        self._rest_samples: int | None = None
        self._end_s: float | None = None
        rate = campaign.spec.daq.rate_hz or rig.daq.rate_hz
        read_s = campaign.spec.daq.read_interval_s or rig.daq.read_interval_s
        faults = run_index == sim.sim_fault_run
        tool = campaign.tool
        if sim.tool_max_chip_mm is not None and ENDMILL.describes(tool):
            tool = tool.model_copy(update={"max_chip_mm": sim.tool_max_chip_mm})
        self.machine = SimMachine(
            tool,
            campaign.material,
            rig.dynamometer,
            _make_stock(campaign, plan),
            rate,
            SignalSettings(sim.noise_n, sim.drift_n_s, sim.hum_n, sim.hum_hz,
                           sim.seed + run_index),
            tool_modes=sim.tool_modes,
            force_model=sim.force_model,
        )  # fmt: skip
        self.controller = self._make_controller(campaign, faults)
        self.controller.lockstep = True
        self.controller.add_listener(
            on_segment=self.machine.on_segment,
            on_spindle=self.machine.on_spindle,
            on_event=self._on_event,
        )
        overflow = []
        if faults and sim.sim_daq_overflow_at_s is not None:
            overflow = [int(sim.sim_daq_overflow_at_s * rate)]
        dyno = rig.dynamometer
        self.daq = SimDaq(
            self._source,
            rate_hz=rate,
            channels=tuple(f"sim/ai{i}" for i in range(len(dyno.channels))),
            channel_names=tuple(ch.name for ch in dyno.channels),
            clock=self.sim_clock,
            read_interval_s=read_s,
            input_range_v=rig.daq.input_range_v,
            sim_overflow_at=overflow,
        )
        self.daq.lockstep = True  # a suspender's hold acts at the end of the block it judged
        self.interlock_at_s = sim.sim_interlock_at_s if faults else None
        self.link_timeout_s = sim.link_timeout_s
        self._serial = campaign.machine.serial
        self._fault: str | None = None
        self._ended = threading.Event()
        self._stream_done = threading.Event()
        self._program: Program | None = None
        self._thread: threading.Thread | None = None
        self._timer: threading.Thread | None = None
        self._stop = threading.Event()
        self.port = self.controller.start()

    def _source(self, t0_s: float, n: int, rate_hz: float) -> np.ndarray:
        """The machine's volts, after the controller has run up to the block's end (the next
        sample's time, where the DAQ's gate holds the clock): what happens there (a GRBL override
        due on the segment grid splits the line) is then in the timeline before the samples are
        computed, not added by the controller's thread while they are (a rounding apart)."""
        daq_t0 = self.daq._t0_s  # the DAQ's own expression of its gate, to the last bit
        self.controller.advance_to(daq_t0 + (round((t0_s - daq_t0) * rate_hz) + n) / rate_hz)
        return self.machine.source(t0_s, n, rate_hz)

    def _make_controller(self, campaign: SimCampaign, faults: bool) -> SimFanuc | SimGrbl:
        sim = campaign.spec.sim
        kw: dict[str, Any] = {}
        if faults and sim.sim_controller_stall_after_block is not None:
            kw["sim_stop_answering_after_block"] = sim.sim_controller_stall_after_block
        if faults and sim.sim_alarm_at_block is not None:
            kw["sim_alarm_at_block"] = (sim.sim_alarm_at_block, 1)
        from rig.sim.controllers import controller_class

        Ctrl = controller_class(self.rules.name)
        baud = campaign.machine.serial.baudrate
        return Ctrl(campaign.machine, clock=self.sim_clock, baudrate=baud, **kw)

    # -- controller events -----------------------------------------------------------------------
    def _on_event(self, ev: Any) -> None:
        if ev.kind == "program_end":
            if self._end_s is None:
                self._end_s = ev.t_s
                self._gate_tail(ev.t_s)
            self._ended.set()
        elif ev.kind == "alarm" and self._fault is None:
            self._fault = f"controller alarm {ev.detail} at t = {ev.t_s:.3f} s"
        elif ev.kind in ("overrun", "port_dropped", "error") and self._fault is None:
            self._fault = f"controller {ev.kind}: {ev.detail}"

    # -- deterministic pacing --------------------------------------------------------------------
    def _block_end_time(self, k: int) -> float:
        """Run-clock time of the end of the DAQ block holding device sample ``k - 1`` (the
        DAQ's own expression, so its wait ends exactly there)."""
        block = self.daq.info.block_samples
        kk = -(-k // block) * block
        return self.daq._t0_s + kk / self.daq.info.rate_hz

    def arm(self, rest_samples: int) -> None:
        """The run has started the DAQ and takes ``rest_samples`` at rest before the program and
        after its end: simulated time runs to the end of the DAQ block that completes the first
        rest and waits there for the program's first byte (:meth:`start`); after the program's
        end it stops at the end of the block that completes the second rest. So the program
        starts and the recording ends at the same simulated times however busy the host."""
        self._rest_samples = int(rest_samples)
        self.sim_clock.gate("arm", self._block_end_time(self._rest_samples))

    def _gate_tail(self, t_end: float) -> None:
        if self._rest_samples is None:
            return
        rate, t0 = self.daq.info.rate_hz, self.daq._t0_s
        k0 = max(0, math.ceil((t_end - t0) * rate))
        while k0 > 0 and t0 + (k0 - 1) / rate >= t_end:
            k0 -= 1
        while t0 + k0 / rate < t_end:
            k0 += 1
        self.sim_clock.gate("end", self._block_end_time(k0 + self._rest_samples))

    def program_end_s(self) -> float | None:
        """Simulated time the controller reached the program's end (None: not yet)."""
        return self._end_s

    # -- RigSession ------------------------------------------------------------------------------
    def start(self, program: Program, writer: object) -> None:
        from rig.dnc import streamer_class
        from rig.dnc.port import line_bytes_per_s

        self._program = program
        cfg = self._serial.model_copy(update={"port": self.port, "timeout_s": self.link_timeout_s})
        cls = streamer_class(self.rules.name)
        # The controller receives at the baud rate in simulated time, so the streamer paces
        # at the line rate times the clock's speed (on a pty it would pace in wall time and
        # starve a controller that runs faster than real time).
        pace = line_bytes_per_s(cfg) * self.sim_clock.speed
        self.streamer = cls(cfg, sink=LoggerSink(writer), clock=self.clock,
                            pace_bytes_per_s=pace)  # fmt: skip
        if hasattr(self.controller, "peer"):  # GRBL's conversation in lockstep too
            from rig.sim._grbl_lockstep import StreamerPeer

            peer = StreamerPeer(self.sim_clock, self.controller, self.streamer)
            self.streamer.lockstep = peer  # type: ignore[union-attr]
            self.controller.peer = peer

        def stream() -> None:
            try:
                self.controller.expect_stream()
                self.sim_clock.gate("arm", None)
                self.streamer.send(program)
            except StreamFault as exc:
                if self._fault is None:
                    self._fault = f"DNC stream fault ({exc.kind}): {exc}"
            except (DncError, RigError, OSError) as exc:
                if self._fault is None:
                    self._fault = f"DNC: {exc}"
            finally:
                link = getattr(self.streamer, "link", None)
                written = None if link is None else link.bytes_written + link.realtime_bytes
                self.controller.end_stream(written)
                self._stream_done.set()

        self._thread = threading.Thread(target=stream, name="sim-stream", daemon=True)
        self._thread.start()
        if self.interlock_at_s is not None:
            t_trip = self.clock() + self.interlock_at_s

            def trip() -> None:
                if self.sim_clock.sleep_until(t_trip, self._stop) and not self._ended.is_set():
                    self.controller.feed_hold()
                    self.controller.reset()
                    self.machine.on_spindle(self.clock(), 0.0)  # door open: spindle stops
                    if self._fault is None:
                        self._fault = f"interlock: door opened at t = {t_trip:.3f} s (sim)"

            self._timer = threading.Thread(target=trip, name="sim-interlock", daemon=True)
            self._timer.start()

    def finished(self) -> bool:
        return self._ended.is_set() or self._fault is not None

    def fault(self) -> str | None:
        return self._fault

    def progress(self) -> tuple[int, int]:
        n = len(self._program.blocks) if self._program is not None else 0
        return min(self.controller.last_completed_block + 1, n), n

    def executed_blocks(self) -> list[tuple[int, float, float, str]]:
        """(order received, start s, end s, text) of every block the controller executed, on
        the run clock: the block clock the samples share."""
        self._stream_over()
        return [(b.seq, b.t_start_s, b.t_end_s, b.text) for b in self.controller.executed]

    def _stream_over(self) -> None:
        """Wait for the streamer's end: the block table's rows are its, its sink appends them
        when the stream ends (for GRBL after the Idle report that follows the program's end);
        starts set before that were lost ("rows never appended") and the streamer's estimates
        stayed, and its end event fell among the run's notes, now and then."""
        if self._thread is not None:
            self._stream_done.wait(self.link_timeout_s + 5.0)

    def block_starts(self) -> tuple[list[int], list[float]]:
        """The controller's own record of when each block it took started, on the run clock:
        (row of the block table, i.e. order received; start s), the finished blocks and the one
        running or held when it stopped. Blocks it never started are left out."""
        self._stream_over()
        ctl = self.controller
        with ctl._lock:  # (the held block a stop's reset cut short is among them)
            starts = dict(ctl.started_s)
        rows = sorted(starts)
        return rows, [starts[k] for k in rows]

    def feed_hold(self) -> None:
        self.controller.feed_hold()

    def cycle_start(self) -> None:
        self.controller.cycle_start()

    def stop(self) -> None:
        """Feed hold, then reset (ends the program, spindle off); the streamer stops too."""
        self.controller.feed_hold()
        self.controller.reset()
        # RESET stops the spindle: the machine must stop rubbing the stock.
        self.machine.on_spindle(self.clock(), 0.0)
        stop = getattr(getattr(self, "streamer", None), "stop", None)
        if stop is not None:
            stop()

    def close(self) -> None:
        self._stop.set()
        for name in ("arm", "end"):
            self.sim_clock.gate(name, None)
        stop = getattr(getattr(self, "streamer", None), "stop", None)
        if stop is not None and not self._stream_done.is_set():
            stop()
        if self._thread is not None:
            self._thread.join(timeout=self.link_timeout_s + 5)
        self.controller.stop()


def sim_session(campaign: SimCampaign, plan: SimPlan, run_index: int) -> SimSession:
    """The campaign runner's session factory for ``rig = "sim"``."""
    return SimSession(campaign, plan, run_index)

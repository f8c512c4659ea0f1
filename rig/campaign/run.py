"""One run of a campaign: arm the DAQ, zero, stream, watch the suspenders, stop, store.

The run talks to the rig only through a :class:`RigSession` (simulated: :mod:`rig.sim.session`,
real: :mod:`rig.campaign.real`), so the same sequence runs on both::

    daq.start(tap)            tap = the run writer behind a sink that watches forces and events
    zero                      mean of the first ``zero_s`` of samples (spindle off, no load)
    session.start(program)    the streamer runs in its own thread; blocks go to the run record
    wait                      until the control has executed the program, watching suspenders:
                              force above the limit or chatter in the last revolutions
                              (analysis.chatter) -> feed hold (then abort), DAQ overflow ->
                              stop, controller fault or alarm -> stop, operator Ctrl-C -> feed
                              hold, then resume or abort
    tail                      ``zero_s`` more of samples at rest; drift fitted on both rests
    daq.stop, writer.close    with the exit status (success, abort, fail) and the reason

Pause is a feed hold: the program is never rewound, the spindle keeps turning, and resuming
continues the same cut.
"""

from __future__ import annotations

import math
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np

from analysis.runs import file as rf
from rig.campaign.chatter_watch import ChatterWatch, ChatterWatchConfig
from rig.campaign.tap import RunRecorder, RunTap
from rig.daq import Daq
from rig.daq.calibration import Calibration, CalibrationError, compensate, fit_drift
from rig.dnc import Program

STATUS_SUCCESS, STATUS_ABORT, STATUS_FAIL = rf.STATUS_SUCCESS, rf.STATUS_ABORT, rf.STATUS_FAIL
#: s of run clock added to twice the program's expected time before a run is declared hung.
WATCHDOG_MARGIN_S = 30.0


class RigSession(Protocol):
    """What a run needs from a rig (simulated or real), for one program."""

    clock: Callable[[], float]

    @property
    def daq(self) -> Daq:
        """The rig's DAQ (read only here: a session has its own kind, simulated or NI)."""

    def start(self, program: Program, writer: RunRecorder) -> None:
        """Begin streaming ``program`` in the background; blocks are recorded in ``writer``."""

    def finished(self) -> bool:
        """The control has executed the whole program (or the stream has stopped)."""

    def fault(self) -> str | None:
        """Why the control or the link failed (stream fault, alarm, interlock), else None."""

    def progress(self) -> tuple[int, int]:
        """(blocks executed, blocks in the program)."""

    def executed_blocks(self) -> list[tuple[int, float, float, str]]:
        """(order received, start s, end s, text) per executed block where the control tells."""

    def feed_hold(self) -> None: ...

    def cycle_start(self) -> None: ...

    def stop(self) -> None:
        """Stop safely: feed hold, then end the program (reset), spindle off."""

    def close(self) -> None: ...


@dataclass(frozen=True)
class RunOutcome:
    status: str
    reason: str
    peak_force_n: float
    samples: int
    wall_s: float


class StopRequest:
    """Set by the Ctrl-C handler (and by tests): the operator wants to pause or stop.

    ``source`` says who asked, the last request's: "Ctrl-C", "SIGTERM", "console (client
    ADDRESS)"; :meth:`reason` puts it in the run's reason."""

    def __init__(self) -> None:
        self.event = threading.Event()
        self.kill = False  # True: stop without asking (SIGTERM, second Ctrl-C)
        self.source = ""

    def request(self, kill: bool = False, source: str = "") -> None:
        self.kill = self.kill or kill
        self.source = source
        self.event.set()

    def reason(self) -> str:
        s = self.source
        if s == "SIGTERM":
            return "stopped by SIGTERM"
        if s.startswith("console"):
            return f"operator stopped the run from the {s}"
        if s == "Ctrl-C":
            return "operator stopped the run (Ctrl-C)"
        return f"the run was stopped ({s or 'no source given'})"


def _ask_resume(prompt: str) -> bool:
    """Ask the operator (only on a terminal); anything but 'r' aborts."""
    if not sys.stdin or not sys.stdin.isatty():
        return False
    try:
        return input(prompt).strip().lower().startswith("r")
    except (EOFError, KeyboardInterrupt):
        return False


@dataclass(frozen=True)
class Suspenders:
    """What stops a run on its own (the campaign's ``[suspenders]``): the resultant force
    limit (N; None: no limit) and what it does (``hold``: feed hold, abort after
    ``hold_timeout_s``; ``abort``: at once); a DAQ overflow ``fail`` or ``continue``;
    ``watchdog_wall_s`` of wall time beyond the run clock's deadline before a run is hung."""

    force_limit_n: float | None = None
    on_force: Literal["hold", "abort"] = "hold"
    hold_timeout_s: float = 0.0
    on_overflow: Literal["fail", "continue"] = "fail"
    watchdog_wall_s: float = 10.0


@dataclass(frozen=True)
class RunConfig:
    """One run's settings: its suspenders, the chatter watch (off unless ``chatter.on_chatter``
    is ``hold`` or ``abort`` with a spindle speed), ``zero_s`` of rest before and after the
    cut, the program's ``expected_s`` (the watchdog allows twice that plus
    :data:`WATCHDOG_MARGIN_S`) and a simulated rig's ``sim_speed`` (1: real time)."""

    suspenders: Suspenders = Suspenders()
    chatter: ChatterWatchConfig = ChatterWatchConfig()
    zero_s: float = 0.2
    expected_s: float = 60.0
    sim_speed: float = 1.0


def execute_run(
    session: RigSession,
    program: Program,
    writer: RunRecorder,
    cal: Calibration,
    config: RunConfig,
    stop: StopRequest,
    progress: Callable[[int, int], None] | None = None,
) -> RunOutcome:
    """Run ``program`` on ``session`` into ``writer`` (already holding conditions and program)
    with ``config``; ``stop`` is the operator's request, ``progress(done, total)`` is told the
    blocks executed. Module docstring: the sequence."""
    return _Run(session, program, writer, cal, config, stop, progress).execute()


class _Run:
    """One run's state between the steps of :func:`execute_run`."""

    def __init__(
        self, session: RigSession, program: Program, writer: RunRecorder, cal: Calibration,
        config: RunConfig, stop: StopRequest, progress: Callable[[int, int], None] | None,
    ) -> None:  # fmt: skip
        self.wall0 = time.monotonic()
        self.session, self.program, self.writer, self.stop = session, program, writer, stop
        self.cfg, self.sus, self.progress = config, config.suspenders, progress
        self.held_at: list[float] = []
        self.held_sim: list[float] = []  # simulated s of the suspender's hold (a simulated rig)
        self.held_since: float | None = None
        self.simulated = bool(getattr(session, "simulated", False))
        clock = getattr(session, "sim_clock", None)
        self.sim_gate: Callable[[str, float | None], None] | None = (
            getattr(clock, "gate", None) if self.simulated else None
        )
        self.status, self.reason = STATUS_SUCCESS, "program completed"
        self.rate = session.daq.info.rate_hz
        ch = config.chatter
        watch = None
        if ch.on_chatter != "none" and ch.spindle_rpm:
            watch = ChatterWatch(tuple(cal.channel_names), self.rate, abs(ch.spindle_rpm),
                                 ch.floor_n, ch.settings)  # fmt: skip
        self.tap = RunTap(writer, cal, self.sus.force_limit_n, self.hold_now, watch)
        self.tap.put_block = getattr(writer, "put_block", None) if self.simulated else None
        self.n_rest = max(2, int(round(config.zero_s * self.rate)))
        if self.simulated:  # its clock stops at the end of each rest: keep a rest and two blocks
            self.tap.history_samples = self.n_rest + 2 * session.daq.info.block_samples
        self.wait_rest_s = 10.0 + 3 * config.zero_s / config.sim_speed
        self.catch_up_s = 60.0  # wall s a lagging simulated DAQ may take to deliver what it owes

    def _act(self) -> str:
        """What the tripped suspender does: the force limit's or the chatter watch's action."""
        return self.sus.on_force if self.tap.over_limit is not None else self.cfg.chatter.on_chatter

    def hold_now(self, why: str) -> None:
        self.session.feed_hold()
        self.held_at.append(time.monotonic())
        if self.sim_gate is not None and not self.held_sim:
            # On a simulated rig the suspender's stop comes at a simulated time, not when the
            # runner's loop happens to look: the clock waits for it there (abort: at the hold;
            # hold: when the hold has lasted hold_timeout_s), so a busy host changes nothing.
            t = self.session.clock()
            self.held_sim.append(t)
            self.sim_gate("suspender", t if self._act() == "abort" else t + self.sus.hold_timeout_s)
        self.writer.event(rf.EV_PAUSE, f"suspender: {why}: feed hold")

    def execute(self) -> RunOutcome:
        session, tap = self.session, self.tap
        session.daq.start(tap)
        try:
            t_zero, v_zero, cal0 = self._zero_and_start()
            self._watch()
            self._conclude()
            self._record_blocks()
            self._rest_after(t_zero, v_zero, cal0)
        except TimeoutError as exc:
            self.status, self.reason = STATUS_FAIL, f"DAQ: {exc}"
            session.stop()
        finally:
            # the DAQ stops before the suspender's gate lifts: a simulated run keeps the samples
            # up to the stop, not what a slow runner let pass after it
            session.daq.stop()
            if self.sim_gate is not None:
                self.sim_gate("suspender", None)
            session.close()
        if (
            tap.daq_fault is not None
            and self.status == STATUS_SUCCESS
            and (self.sus.on_overflow == "continue")
        ):
            self.reason = f"program completed; {tap.daq_fault}"
        return RunOutcome(self.status, self.reason, tap.peak_force_n, tap.samples,
                          time.monotonic() - self.wall0)  # fmt: skip

    def _zero_and_start(self) -> tuple[np.ndarray, np.ndarray, Calibration]:
        """Zero on the rest before the cut, then start streaming: (rest times s, volts, zeroed
        calibration)."""
        session, tap, writer = self.session, self.tap, self.writer
        arm = getattr(session, "arm", None)
        if arm is not None:  # a simulated rig: program start and end on its own clock
            arm(self.n_rest)
        t_zero, v_zero = tap.capture(self.n_rest, self.wait_rest_s)
        cal0 = tap.cal.zeroed(v_zero, float(t_zero.mean()))
        tap.cal = cal0
        writer.set_calibration(cal0, "zeroed at rest before the cut (reset/operate)")
        tap.monitor = True
        writer.event(rf.EV_START, f"streaming {self.program.name}")
        session.start(self.program, writer)
        return t_zero, v_zero, cal0

    def _end(self, status: str, reason: str) -> bool:
        self.status, self.reason = status, reason
        return True

    def _watch(self) -> None:
        """Until the control has executed the program, or something ends the run (its status
        and reason)."""
        session, cfg = self.session, self.cfg
        # Watchdog on the run clock: a control that stops answering after it has read the whole
        # program (drip feed has no acknowledgement) would otherwise be waited for forever.
        limit_s = 2.0 * cfg.expected_s + WATCHDOG_MARGIN_S
        deadline = session.clock() + limit_s
        # ... and in wall time too (``watchdog_wall_s`` more): on a busy computer a simulated
        # link can fall behind its clock.
        deadline_wall = time.monotonic() + limit_s / cfg.sim_speed + self.sus.watchdog_wall_s
        while not session.finished():
            time.sleep(0.02)
            if self.progress is not None:
                self.progress(*session.progress())
            if self.stop.event.is_set():
                if self._operator_resumes():
                    continue
                self._end(STATUS_ABORT, f"{self.stop.reason()}: feed hold, stop")
                return
            if self._failed(limit_s, deadline, deadline_wall) or self._suspended():
                return

    def _operator_resumes(self) -> bool:
        """Feed hold on the operator's stop; True when the operator resumes the cut."""
        stop, writer = self.stop, self.writer
        self.session.feed_hold()
        writer.event(rf.EV_PAUSE, f"stop ({stop.source or 'no source given'}): feed hold")
        if not stop.kill and _ask_resume("\ncutlab: paused (feed hold). [r]esume or [a]bort? "):
            stop.event.clear()
            self.session.cycle_start()
            writer.event(rf.EV_RESUME, "operator: cycle start")
            return True
        return False

    def _failed(self, limit_s: float, deadline: float, deadline_wall: float) -> bool:
        """True (status and reason set) when the DAQ, the medium, the watchdog or the control
        ends the run."""
        session, tap = self.session, self.tap
        if tap.daq_fault is not None and self.sus.on_overflow == "fail":
            return self._end(STATUS_FAIL, tap.daq_fault)
        medium = getattr(self.writer, "failure", None)  # disk nearly full, write error
        if medium is not None:
            return self._end(STATUS_FAIL, medium)
        if (
            self.held_since is None
            and not self.stop.event.is_set()
            and session.clock() > deadline
            and time.monotonic() > deadline_wall
        ):
            done, total = session.progress()
            return self._end(STATUS_FAIL, (
                f"controller stopped answering: the program did not end within {limit_s:.0f}"
                f" s (expected {self.cfg.expected_s:.0f} s); {done} of {total} blocks executed"
            ))  # fmt: skip
        fault = session.fault()
        if fault is not None:
            if "interlock" in fault:
                self.writer.event(rf.EV_INTERLOCK, fault)
                return self._end(STATUS_ABORT, fault)
            return self._end(STATUS_FAIL, fault)
        return False

    def _suspended(self) -> bool:
        """True (status and reason set) when a tripped suspender aborts the run: at once, or
        once its hold has lasted ``hold_timeout_s``."""
        tripped = self.tap.over_limit or self.tap.chatter_found
        if tripped is None or not self.held_at:
            return False
        self.held_since = self.held_at[0]
        waited_wall_s = time.monotonic() - self.held_since
        hold_s = self.sus.hold_timeout_s
        if self.held_sim:  # the gate's own expression: the clock stands exactly there
            timed_out = self.session.clock() >= self.held_sim[0] + hold_s or (
                waited_wall_s >= hold_s / self.cfg.sim_speed + self.catch_up_s
            )
        else:
            timed_out = waited_wall_s >= hold_s
        if self._act() == "abort" or timed_out:
            return self._end(STATUS_ABORT, f"suspender: {tripped}")
        return False

    def _conclude(self) -> None:
        """The fault event and the stop of a run that did not succeed; a control fault noticed
        after the program ended fails it."""
        session = self.session
        if self.status == STATUS_FAIL:
            self.writer.event(rf.EV_FAULT, self.reason)
        if self.status != STATUS_SUCCESS:
            session.stop()
        elif session.fault() is not None:
            self.status, self.reason = STATUS_FAIL, session.fault() or ""
        if self.progress is not None:
            self.progress(*session.progress())

    def _record_blocks(self) -> None:
        """When each block ran, on the run clock: ties every sample to the block cutting then."""
        session, writer = self.session, self.writer
        for seq, t0, t1, text in session.executed_blocks():
            msg = f"executed block {seq} {t0:.6f}..{t1:.6f} s: {text}"
            writer.event(rf.EV_NOTE, msg, time_s=t0)
        # The block table's execution starts from the controller's own record where it keeps
        # one (the simulated rig): the streamer's estimate knows nothing of a feed hold.
        starts = getattr(session, "block_starts", None)
        set_exec = getattr(writer, "set_exec_times", None)
        if starts is not None and set_exec is not None:
            rows, t_starts = starts()
            set_exec(rows, t_starts, complete=True)
            # at the last start (the simulated rig's record), not when this thread got here
            writer.event(rf.EV_NOTE, "block table: execution starts from the controller's "
                                     f"record ({len(rows)} blocks started)",
                         time_s=max(t_starts) if t_starts else None)  # fmt: skip

    def _rest_after(self, t_zero: np.ndarray, v_zero: np.ndarray, cal0: Calibration) -> None:
        """Rest after the cut: zero and drift from both rests (not after a failure: the rig may
        not be at rest, so the zero taken before the cut stays)."""
        session, tap, writer = self.session, self.tap, self.writer
        end_of = getattr(session, "program_end_s", None)
        t_prog_end = end_of() if end_of is not None and self.status == STATUS_SUCCESS else None
        t_end = session.clock() if t_prog_end is None else t_prog_end
        if self.status != STATUS_SUCCESS:
            self._keep_until(t_end)
            return
        try:
            t_tail, v_tail = tap.capture(self.n_rest, self.wait_rest_s + self.catch_up_s,
                                         from_s=t_end)  # fmt: skip
            fit = fit_drift(
                np.concatenate([t_zero, t_tail]),
                np.vstack([v_zero, v_tail]),
                np.ones(len(t_zero) + len(t_tail), bool),
                t_ref_s=float(t_zero.mean()),
            )
            writer.set_calibration(compensate(cal0, fit), "drift fitted on the rests")
        except (TimeoutError, CalibrationError) as exc:
            writer.event(rf.EV_NOTE, f"no drift fit: {exc}")

    def _keep_until(self, t_end: float) -> None:
        """Keep what was acquired up to the stop, even if the DAQ lags the clock (briefly when
        the DAQ itself failed: it may never deliver again)."""
        tap = self.tap
        if not (self.held_sim and self.sim_gate is not None):
            tap.wait_until(t_end, 5.0 if tap.daq_fault else self.catch_up_s)
            return
        # a simulated rig stopped by a suspender records a rest of zero_s after the stop (the
        # spindle stopped), to the end of a DAQ block, the clock waiting there until the DAQ is
        # stopped: the same samples however busy the host
        blk, t0_daq = self.session.daq.info.block_samples, tap.t0_s
        k = math.ceil((t_end + self.cfg.zero_s - t0_daq) * self.rate / blk) * blk
        self.sim_gate("suspender", t0_daq + k / self.rate)
        tap.wait_until(t0_daq + (k - 1) / self.rate, self.catch_up_s)

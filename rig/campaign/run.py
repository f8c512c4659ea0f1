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
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from analysis.runs import file as rf
from rig.campaign.chatter_watch import ChatterWatch
from rig.daq import SAMPLE_FORMAT_RAW, Daq, DaqEvent, DaqInfo
from rig.daq.calibration import Calibration, CalibrationError, compensate, fit_drift
from rig.dnc import Program

STATUS_SUCCESS, STATUS_ABORT, STATUS_FAIL = rf.STATUS_SUCCESS, rf.STATUS_ABORT, rf.STATUS_FAIL
#: s of run clock added to twice the program's expected time before a run is declared hung.
WATCHDOG_MARGIN_S = 30.0
#: wall s a simulated DAQ's block waits for room in the writer's queue before it is dropped
LOSSLESS_WAIT_S = 60.0


class RigSession(Protocol):
    """What a run needs from a rig (simulated or real), for one program."""

    daq: Daq
    clock: Callable[[], float]

    def start(self, program: Program, writer: object) -> None:
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


class _Tap:
    """DAQ sink in front of the run writer: forwards everything; keeps the rest windows for the
    zero and the drift fit; computes forces to watch the force limit; notes DAQ faults."""

    def __init__(
        self,
        writer: object,
        cal: Calibration,
        force_limit_n: float | None,
        on_over_limit: Callable[[str], None] | None = None,
        chatter: ChatterWatch | None = None,
    ) -> None:
        self.writer = writer
        self.on_over_limit = on_over_limit
        self.chatter = chatter
        self.chatter_found: str | None = None
        self.lossless = False
        self.cal = cal
        self.force_limit_n = force_limit_n
        self.monitor = False
        self.info: DaqInfo | None = None
        self.t0_s = math.nan
        self.samples = 0
        self.peak_force_n = 0.0
        self.over_limit: str | None = None
        self.daq_fault: str | None = None
        self._capture: list[tuple[np.ndarray, np.ndarray]] | None = None
        # the latest blocks, so a capture asked for after its samples came takes them (a
        # simulated rig's clock waits at the end of a rest, which a fast DAQ may reach before
        # the runner asks for it: the capture then waited for samples that never came)
        self.history_samples = 0
        self._history: deque[tuple[np.ndarray, np.ndarray]] = deque()
        self._capture_n = 0
        self._capture_from = -math.inf
        self._captured = threading.Event()
        self._lock = threading.Lock()
        self._progress = threading.Condition()
        self.t_last_s = -math.inf  # run-clock time of the last sample delivered

    # -- DaqSink ---------------------------------------------------------------------------------
    def on_start(self, info: DaqInfo, t0_s: float) -> None:
        self.info = info
        self.t0_s = t0_s
        self.writer.on_start(info, t0_s)

    def on_block(self, first_sample: int, data: np.ndarray) -> None:
        if self.lossless:
            # A simulated DAQ waits for the writer (its clock waits with it): a busy host must
            # not drop samples a quiet one keeps.
            self.writer.put_block(first_sample, data, timeout_s=LOSSLESS_WAIT_S)
        else:
            self.writer.on_block(first_sample, data)
        info = self.info
        n = data.shape[1]
        self.samples = first_sample + n
        if info.sample_format == SAMPLE_FORMAT_RAW:
            volts = rf.raw_to_volts(data.T, info.scaling_coeff)
        else:
            volts = np.array(data.T, dtype=float)
        t = self.t0_s + (first_sample + np.arange(n)) / info.rate_hz
        with self._lock:
            if self._capture is not None:
                keep = t >= self._capture_from
                if keep.any():
                    self._capture.append((t[keep], volts[keep]))
                if sum(len(c[0]) for c in self._capture) >= self._capture_n:
                    self._captured.set()
            if self.history_samples > 0:
                self._history.append((t, volts))
                while sum(len(h[0]) for h in self._history) - len(self._history[0][0]) >= (
                    self.history_samples
                ):
                    self._history.popleft()
            if self.monitor:
                f = self.cal.force_from_volts(volts, t)
                peak = float(np.max(np.linalg.norm(f, axis=1))) if n else 0.0
                self.peak_force_n = max(self.peak_force_n, peak)
                if self.force_limit_n is not None and peak > self.force_limit_n:
                    if self.over_limit is None:
                        k = int(np.argmax(np.linalg.norm(f, axis=1)))
                        self.over_limit = (
                            f"force {peak:.0f} N above the limit {self.force_limit_n:.0f} N at "
                            f"t = {t[k]:.3f} s"
                        )
                        # Act from the acquisition thread: waiting for the runner's next look
                        # would let the cut go on for its polling interval.
                        if self.on_over_limit is not None:
                            self.on_over_limit(self.over_limit)
                if self.chatter is not None and self.chatter_found is None:
                    found = self.chatter.push(f)
                    if found is not None:
                        self.chatter_found = f"{found} at t = {t[-1]:.3f} s"
                        if self.on_over_limit is not None:
                            self.on_over_limit(self.chatter_found)
        with self._progress:
            self.t_last_s = float(t[-1]) if n else self.t_last_s
            self._progress.notify_all()

    def on_event(self, event: DaqEvent) -> None:
        self.writer.on_event(event)
        if event.kind in (rf.EV_OVERFLOW, rf.EV_FAULT) and self.daq_fault is None:
            self.daq_fault = f"DAQ {event.kind} at sample {event.sample}: {event.message}"

    # -- rest windows ----------------------------------------------------------------------------
    def wait_until(self, t_s: float, timeout_s: float) -> bool:
        """Wait until the DAQ has delivered the samples up to run-clock time ``t_s`` (a
        simulated DAQ may lag the clock when the CPU is busy; its samples still come in order)."""
        with self._progress:
            return self._progress.wait_for(lambda: self.t_last_s >= t_s, timeout_s)

    def capture(
        self, n: int, timeout_s: float, from_s: float = -math.inf
    ) -> tuple[np.ndarray, np.ndarray]:
        """The next ``n`` samples per channel taken at or after run-clock time ``from_s``:
        (time_s (n,), volts (n, c)); waits for them."""
        with self._lock:
            self._capture, self._capture_n = [], n
            self._capture_from = from_s
            self._captured.clear()
            for t, v in self._history:  # what came before the call, from from_s on
                keep = t >= from_s
                if keep.any():
                    self._capture.append((t[keep], v[keep]))
            if sum(len(c[0]) for c in self._capture) >= n:
                self._captured.set()
        ok = self._captured.wait(timeout_s)
        with self._lock:
            parts, self._capture = self._capture or [], None
        if not ok or not parts:
            raise TimeoutError(f"no samples from the DAQ within {timeout_s:.1f} s")
        t = np.concatenate([p[0] for p in parts])[:n]
        v = np.concatenate([p[1] for p in parts])[:n]
        return t, v


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


def execute_run(
    session: RigSession,
    program: Program,
    writer: object,
    cal: Calibration,
    *,
    force_limit_n: float | None,
    on_force: str,
    hold_timeout_s: float,
    on_overflow: str,
    stop: StopRequest,
    zero_s: float = 0.2,
    expected_s: float = 60.0,
    progress: Callable[[int, int], None] | None = None,
    sim_speed: float = 1.0,
    watchdog_wall_s: float = 10.0,
    on_chatter: str = "none",
    spindle_rpm: float = 0.0,
    chatter_floor_n: float = 10.0,
    chatter_settings: object = None,
) -> RunOutcome:
    """Run ``program`` on ``session`` into ``writer`` (already holding conditions and program).
    ``on_chatter`` "hold" or "abort" (with ``spindle_rpm`` > 0) watches the live force for
    chatter (:class:`ChatterWatch`, judged with ``chatter_settings``, an
    ``analysis.chatter.ChatterSettings``) and holds or aborts as the force limit does."""
    wall0 = time.monotonic()
    held_at: list[float] = []
    held_sim: list[float] = []  # simulated s of the suspender's hold (a simulated rig)
    simulated = bool(getattr(session, "simulated", False))
    sim_gate = getattr(getattr(session, "sim_clock", None), "gate", None) if simulated else None

    def hold_now(why: str) -> None:
        session.feed_hold()
        held_at.append(time.monotonic())
        if sim_gate is not None and not held_sim:
            # On a simulated rig the suspender's stop comes at a simulated time, not when the
            # runner's loop happens to look: the clock waits for it there (abort: at the hold;
            # hold: when the hold has lasted hold_timeout_s), so a busy host changes nothing.
            t = session.clock()
            held_sim.append(t)
            act = on_force if tap.over_limit is not None else on_chatter
            sim_gate("suspender", t if act == "abort" else t + hold_timeout_s)
        writer.event(rf.EV_PAUSE, f"suspender: {why}: feed hold")

    status, reason = STATUS_SUCCESS, "program completed"
    daq = session.daq
    rate = daq.info.rate_hz
    watch = None
    if on_chatter != "none" and spindle_rpm:
        watch = ChatterWatch(tuple(cal.channel_names), rate, abs(spindle_rpm), chatter_floor_n,
                              chatter_settings)  # fmt: skip
    tap = _Tap(writer, cal, force_limit_n, hold_now, watch)
    tap.lossless = simulated and hasattr(writer, "put_block")
    n_rest = max(2, int(round(zero_s * rate)))
    if simulated:  # its clock stops at the end of each rest: keep a rest and two blocks
        tap.history_samples = n_rest + 2 * daq.info.block_samples
    wait_rest_s = 10.0 + 3 * zero_s / sim_speed
    catch_up_s = 60.0  # wall s a lagging simulated DAQ may take to deliver what it owes
    daq.start(tap)
    try:
        arm = getattr(session, "arm", None)
        if arm is not None:  # a simulated rig: program start and end on its own clock
            arm(n_rest)
        t_zero, v_zero = tap.capture(n_rest, wait_rest_s)
        cal0 = cal.zeroed(v_zero, float(t_zero.mean()))
        tap.cal = cal0
        writer.set_calibration(cal0, "zeroed at rest before the cut (reset/operate)")
        tap.monitor = True
        writer.event(rf.EV_START, f"streaming {program.name}")
        session.start(program, writer)
        # Watchdog on the run clock: a control that stops answering after it has read the whole
        # program (drip feed has no acknowledgement) would otherwise be waited for forever.
        limit_s = 2.0 * expected_s + WATCHDOG_MARGIN_S
        deadline = session.clock() + limit_s
        # ... and in wall time too (``watchdog_wall_s`` more): on a busy computer a simulated
        # link can fall behind its clock.
        deadline_wall = time.monotonic() + limit_s / sim_speed + watchdog_wall_s
        held_since: float | None = None
        while not session.finished():
            time.sleep(0.02)
            if progress is not None:
                progress(*session.progress())
            if stop.event.is_set():
                session.feed_hold()
                writer.event(rf.EV_PAUSE, f"stop ({stop.source or 'no source given'}): feed hold")
                if not stop.kill and _ask_resume(
                    "\ncutlab: paused (feed hold). [r]esume or [a]bort? "
                ):
                    stop.event.clear()
                    session.cycle_start()
                    writer.event(rf.EV_RESUME, "operator: cycle start")
                    continue
                status, reason = STATUS_ABORT, f"{stop.reason()}: feed hold, stop"
                break
            if tap.daq_fault is not None and on_overflow == "fail":
                status, reason = STATUS_FAIL, tap.daq_fault
                break
            medium = getattr(writer, "failure", None)  # disk nearly full, write error
            if medium is not None:
                status, reason = STATUS_FAIL, medium
                break
            if (
                held_since is None
                and not stop.event.is_set()
                and session.clock() > deadline
                and time.monotonic() > deadline_wall
            ):
                done, total = session.progress()
                status = STATUS_FAIL
                reason = (
                    f"controller stopped answering: the program did not end within {limit_s:.0f}"
                    f" s (expected {expected_s:.0f} s); {done} of {total} blocks executed"
                )
                break
            fault = session.fault()
            if fault is not None:
                status, reason = STATUS_FAIL, fault
                if "interlock" in fault:
                    status = STATUS_ABORT
                    writer.event(rf.EV_INTERLOCK, fault)
                break
            tripped = tap.over_limit or tap.chatter_found
            if tripped is not None and held_at:
                held_since = held_at[0]
                act = on_force if tap.over_limit is not None else on_chatter
                waited_wall_s = time.monotonic() - held_since
                if held_sim:  # the gate's own expression: the clock stands exactly there
                    timed_out = session.clock() >= held_sim[0] + hold_timeout_s or (
                        waited_wall_s >= hold_timeout_s / sim_speed + catch_up_s
                    )
                else:
                    timed_out = waited_wall_s >= hold_timeout_s
                if act == "abort" or timed_out:
                    status, reason = STATUS_ABORT, f"suspender: {tripped}"
                    break
        if status == STATUS_FAIL:
            writer.event(rf.EV_FAULT, reason)
        if status != STATUS_SUCCESS:
            session.stop()
        elif session.fault() is not None:
            status, reason = STATUS_FAIL, session.fault() or ""
        if progress is not None:
            progress(*session.progress())
        # When each block ran, on the run clock: ties every sample to the block cutting then.
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
            writer.event(rf.EV_NOTE, "block table: execution starts from the controller's "
                                     f"record ({len(rows)} blocks started)")  # fmt: skip
        # Rest after the cut: zero and drift from both rests (not after a failure: the rig may
        # not be at rest, so the zero taken before the cut stays).
        end_of = getattr(session, "program_end_s", None)
        t_prog_end = end_of() if end_of is not None and status == STATUS_SUCCESS else None
        t_end = session.clock() if t_prog_end is None else t_prog_end
        if status == STATUS_SUCCESS:
            try:
                t_tail, v_tail = tap.capture(n_rest, wait_rest_s + catch_up_s, from_s=t_end)
                fit = fit_drift(
                    np.concatenate([t_zero, t_tail]),
                    np.vstack([v_zero, v_tail]),
                    np.ones(len(t_zero) + len(t_tail), bool),
                    t_ref_s=float(t_zero.mean()),
                )
                writer.set_calibration(compensate(cal0, fit), "drift fitted on the rests")
            except (TimeoutError, CalibrationError) as exc:
                writer.event(rf.EV_NOTE, f"no drift fit: {exc}")
        else:
            # Keep what was acquired up to the stop, even if the DAQ lags the clock (briefly
            # when the DAQ itself failed: it may never deliver again).
            if not (held_sim and sim_gate is not None):
                tap.wait_until(t_end, 5.0 if tap.daq_fault else catch_up_s)
            else:
                # a simulated rig stopped by a suspender records a rest of zero_s after the stop
                # (the spindle stopped), to the end of a DAQ block, the clock waiting there
                # until the DAQ is stopped: the same samples however busy the host
                blk, t0_daq = daq.info.block_samples, tap.t0_s
                k = math.ceil((t_end + zero_s - t0_daq) * rate / blk) * blk
                sim_gate("suspender", t0_daq + k / rate)
                tap.wait_until(t0_daq + (k - 1) / rate, catch_up_s)
    except TimeoutError as exc:
        status, reason = STATUS_FAIL, f"DAQ: {exc}"
        session.stop()
    finally:
        # the DAQ stops before the suspender's gate lifts: a simulated run keeps the samples up
        # to the stop, not what a slow runner let pass after it
        daq.stop()
        if sim_gate is not None:
            sim_gate("suspender", None)
        session.close()
    if tap.daq_fault is not None and status == STATUS_SUCCESS and on_overflow == "continue":
        reason = f"program completed; {tap.daq_fault}"
    return RunOutcome(status, reason, tap.peak_force_n, tap.samples, time.monotonic() - wall0)

"""The DAQ sink of a campaign run (:class:`RunTap`): in front of the run's recorder, it keeps the
rest windows for the zero and the drift fit, watches the force limit and the chatter in the live
force, and notes DAQ faults."""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Callable
from typing import Protocol

import numpy as np

from analysis.runs import file as rf
from rig.campaign.chatter_watch import ChatterWatch
from rig.daq import SAMPLE_FORMAT_RAW, DaqEvent, DaqInfo
from rig.daq.calibration import Calibration

#: wall s a simulated DAQ's block waits for room in the writer's queue before it is dropped
LOSSLESS_WAIT_S = 60.0


class RunRecorder(Protocol):
    """Where a run is recorded (:class:`rig.log.RunWriter`): the DAQ's samples and events, the
    run's events and its calibration. Looked up by name where a recorder has them:
    ``put_block(first, data, timeout_s=)`` (a simulated DAQ waits for room instead of dropping),
    ``failure`` (the medium failed: the run fails with it) and ``set_exec_times(rows, starts,
    complete=)`` (the control's record of when each block ran)."""

    def on_start(self, info: DaqInfo, t0_s: float) -> None: ...

    def on_block(self, first_sample: int, data: np.ndarray) -> None: ...

    def on_event(self, event: DaqEvent) -> None: ...

    def event(self, kind: str, message: str = "", *, time_s: float | None = None) -> None: ...

    def set_calibration(self, cal: Calibration, message: str = "") -> None: ...


class RunTap:
    """DAQ sink in front of the run writer: forwards everything; keeps the rest windows for the
    zero and the drift fit; computes forces to watch the force limit; notes DAQ faults."""

    def __init__(
        self,
        writer: RunRecorder,
        cal: Calibration,
        force_limit_n: float | None,
        on_over_limit: Callable[[str], None] | None = None,
        chatter: ChatterWatch | None = None,
    ) -> None:
        self.writer = writer
        self.on_over_limit = on_over_limit
        self.chatter = chatter
        self.chatter_found: str | None = None
        # the writer's put_block when a simulated DAQ waits for it (lossless), else None
        self.put_block: Callable[..., None] | None = None
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
        if self.put_block is not None:
            # A simulated DAQ waits for the writer (its clock waits with it): a busy host must
            # not drop samples a quiet one keeps.
            self.put_block(first_sample, data, timeout_s=LOSSLESS_WAIT_S)
        else:
            self.writer.on_block(first_sample, data)
        info = self.info
        assert info is not None  # on_start comes before the first block
        n = data.shape[1]
        self.samples = first_sample + n
        if info.sample_format == SAMPLE_FORMAT_RAW:
            assert info.scaling_coeff is not None  # a raw format comes with its scaling
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

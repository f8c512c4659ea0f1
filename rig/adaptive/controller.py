"""The adaptive controller: live force in, GRBL real-time overrides out (issue 29).

It is a DAQ sink (``on_start`` / ``on_block`` / ``on_event``, called from the acquisition thread
in the same process as the run, behind the run's own sink: :class:`AdaptiveDaq`), so it sees
every block as the run writer does, not a file. Per spindle revolution it reduces the force as
the AFC report measures evenness (:func:`rig.report.afc.cutting_revolutions`): the mean of the
feed-plane resultant ``|Fxy|`` over the revolution. Then, in this order:

1. safety: a sample's resultant above ``max_force_n`` -> feed hold at once (the block it came
   in, at most one DAQ read); no block for ``stall_revs`` revolutions of the run clock beyond
   one DAQ read (a watchdog thread) -> overrides reset and feed hold; chatter confirmed by the
   live watch the campaign's suspender uses (:class:`analysis.chatter.ChatterWatch`: the last
   ``chatter_revs`` revolutions cut at a steady level, a verdict per 0.1 s of samples, two
   chattering verdicts in a row whose power off the harmonics holds) -> with a spindle mode, the
   spindle override to the nearest stable speed of the tool's lobes within 10-200 %, else feed
   hold. After a hold the controller sends nothing more (the operator, or the run, decides).
2. air (the revolution's force below ``air_force_n``): overrides back to 100 %.
3. cutting: outside the dead band (``dead_band_pct`` of the target) the feed override moves
   toward ``pct * target / force`` (force roughly proportional to the feed per tooth), up by at
   most ``slew_up_pct`` per revolution, down by at most ``slew_down_pct`` (lowering the load is
   the safe direction, so it may go faster), within 10-200 % (GRBL 1.1's limits); after a change
   it waits ``settle_revs`` revolutions (the revolution that mixes both feeds is not judged).
   A revolution cut at a limit of the override with the force still outside the dead band on
   the side the limit keeps it from correcting is *saturated*: the target is out of reach there
   (seed 001's 0.1 mm step makes about 74 N at 200 % and at 17 % alike: its load is the edge's,
   not the chip's). Saturation is an event when it starts and when it ends (with its revolutions
   and time), counted in :meth:`summary`, so the report can tell reachable cutting time apart.

Every decision is an event in the run file (kind ``note``, text ``adaptive: ...``; holds are
``pause``), every override byte with its run-clock time, the commanded and last reported
(``Ov:``, ``FS:``) override and feed, the target and the state; :attr:`trace` keeps the same per
revolution in memory for the report and tests.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from analysis.chatter import ChatterSettings, ChatterWatch
from analysis.runs import file as rf
from rig.adaptive.grbl_codes import APPLY_DELAY_S
from rig.adaptive.grbl_codes import feed_codes as _feed_codes
from rig.adaptive.grbl_codes import spindle_codes as _spindle_codes
from rig.adaptive.pockets import nearest_pocket_rpm
from rig.adaptive.record import Decision, RevRecord, loop_status, loop_summary, reported_text
from rig.adaptive.results import AdaptiveStatus, AdaptiveSummary, NoteWriter
from rig.adaptive.saturation import Saturation
from rig.adaptive.settings import MODES, AdaptiveSettings  # noqa: F401 - imported from here too

if TYPE_CHECKING:
    from analysis.stability import Lobes
    from rig.adaptive.feedforward import FeedForward
    from rig.daq import DaqEvent, DaqInfo
    from rig.dnc import GrblStreamer


class AdaptiveController:
    """See the module docstring. ``streamer`` (set later with :meth:`attach`) needs GRBL's
    override API: ``feed_override_pct``, ``spindle_override_pct``, ``override``, ``overrides``,
    ``feed_hold`` and ``last_status``. ``force_of(volts (n, c), t (n,)) -> (n, c) N``;
    ``channels`` the force channels' names (Fx and Fy are judged)."""

    def __init__(
        self,
        settings: AdaptiveSettings,
        *,
        spindle_rpm: float,
        channels: Sequence[str],
        force_of: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
        clock: Callable[[], float] = time.monotonic,
        writer: NoteWriter | None = None,
        lobes: Lobes | None = None,
        depth_mm: float = 0.0,
        chatter_settings: ChatterSettings | None = None,
        on_hold: Callable[[str], None] | None = None,
        feed_forward: FeedForward | None = None,
    ) -> None:
        self.s = settings
        #: the anticipation (rig.adaptive.feedforward.FeedForward) when the program's stock is
        #: known, else None: the measured force alone
        self.ff = feed_forward if settings.mode in ("feed", "both") else None
        self.rpm = abs(float(spindle_rpm))
        if not self.rpm > 0:
            raise ValueError(f"spindle_rpm = {spindle_rpm}: the loop needs a turning spindle")
        self.channels = tuple(channels)
        self.cols = [list(channels).index(c) for c in ("Fx", "Fy") if c in channels] or [0, 1]
        self.force_of = force_of
        self.clock = clock
        self.writer = writer
        self.lobes, self.depth_mm = lobes, depth_mm
        self.chatter_settings = chatter_settings
        self.on_hold = on_hold
        self.streamer: Any = None
        self.rate_hz = math.nan
        self.block_s = math.nan
        self.t0_s = 0.0
        self.feed_pct = 100
        self.spindle_pct = 100
        self.state = "idle"  # idle, air, cutting, hold
        self.stream_over = False  # the program's stream ended: nothing more to override
        self.hold_reason: str | None = None
        self.trace: list[RevRecord] = []
        self.decisions: list[Decision] = []
        self.bytes_sent: list[tuple[float, int]] = []  # (run-clock s, override byte)
        self.latencies_s: list[float] = []
        self.cpu_s = 0.0
        self._lock = threading.RLock()
        self._acc: list[np.ndarray] = []  # |Fxy| samples of the revolution under way
        self._acc_n = 0
        self._chatter: ChatterWatch | None = None  # the live chatter watch at today's speed
        self._verdict: Any = None  # its latest verdict already seen
        self._settle = 0
        # when the last change (spindle move) reaches the motion, run-clock s; the feed % before
        self._applied_at_s, self._new_speed_at_s, self._pct_was = -math.inf, -math.inf, 100
        self._last_block_t = math.nan
        self._armed = False
        self._stop = threading.Event()
        self._watch: threading.Thread | None = None
        self._block_wall = 0.0
        #: a DAQ on another clock than ``clock`` (a plain send): the watchdog counts from each
        #: block's arrival, not its samples' time
        self.stamp_arrival = False
        self.chatter_at_s: float | None = None
        self.chatter_cleared_s: float | None = None
        #: saturation: revolutions at an override limit, the target out of reach there
        self.sat = Saturation(self._note)
        self.saturated_spans = self.sat.spans  # (start s, end s, revs) of each stretch
        self._saturated_now = False

    # -- wiring ----------------------------------------------------------------------------------
    def attach(self, streamer: GrblStreamer) -> None:
        """The GRBL streamer the overrides go through (once it has opened the port)."""
        self.streamer = streamer

    def arm(self) -> None:
        """The program is running: a silent force signal is now a fault (watchdog started)."""
        with self._lock:
            self._armed = True
            self._last_block_t = self.clock()
        if self._watch is None:
            self._watch = threading.Thread(target=self._watchdog, name="adaptive-watch",
                                           daemon=True)  # fmt: skip
            self._watch.start()

    def close(self) -> None:
        """Stop watching (the run is over); sends nothing."""
        with self._lock:
            self._armed = False
            if self.trace:
                self.sat.end(self.trace[-1].t_s)
        self._stop.set()
        if self._watch is not None and self._watch is not threading.current_thread():
            self._watch.join(timeout=2.0)

    @property
    def rev_s(self) -> float:
        return 60.0 / (self.rpm * self.spindle_pct / 100.0)

    @property
    def stall_s(self) -> float:
        """Run-clock s without a block before the signal counts as lost: one DAQ read (the
        blocks' own spacing) plus ``stall_revs`` revolutions."""
        return (self.block_s if math.isfinite(self.block_s) else 0.0) + self.s.stall_revs * (
            60.0 / self.rpm
        )

    # -- DaqSink ---------------------------------------------------------------------------------
    def on_start(self, info: DaqInfo, t0_s: float) -> None:
        self.rate_hz = float(info.rate_hz)
        self.block_s = info.block_samples / self.rate_hz
        self.t0_s = t0_s

    def on_event(self, event: DaqEvent) -> None:
        if event.kind == rf.EV_STOP:
            with self._lock:
                self._armed = False

    def on_block(self, first_sample: int, data: np.ndarray) -> None:
        """Called by the DAQ's thread with (c, n) volts or codes already scaled by the caller
        (:class:`AdaptiveDaq` hands volts); judged when a force function is set."""
        wall0 = time.perf_counter()
        cpu0 = time.thread_time()
        try:
            self._on_block(first_sample, data, wall0)
        finally:
            self.cpu_s += time.thread_time() - cpu0

    def push_forces(self, t_end_s: float, force_n: np.ndarray, wall0: float | None = None) -> None:
        """Judge forces (n, c) N whose last sample is at run-clock ``t_end_s`` (tests and the
        ring reader call this directly)."""
        wall0 = time.perf_counter() if wall0 is None else wall0
        with self._lock:
            self._last_block_t = self.clock() if self.stamp_arrival else t_end_s
            if self.state == "hold" or self.stream_over:
                return
            f = np.asarray(force_n, float)
            if not len(f):
                return
            fxy = f[:, self.cols]
            res = np.linalg.norm(f, axis=1)
            k = int(np.argmax(res))
            n = len(f)
            t_first = t_end_s - (n - 1) / self.rate_hz
            if res[k] > self.s.max_force_n:
                t_k = t_first + k / self.rate_hz
                why = f"force {res[k]:.0f} N above max_force_n {self.s.max_force_n:.0f} N"
                self._hold(f"{why} at t = {t_k:.3f} s", t_end_s, wall0)
                return
            self._acc.append(np.hypot(fxy[:, 0], fxy[:, 1]))
            self._acc_n += n
            spr = int(round(self.rate_hz * self.rev_s))
            while self._acc_n >= spr and self.state != "hold":
                allx = np.concatenate(self._acc)
                rev, rest = allx[:spr], allx[spr:]
                self._acc, self._acc_n = [rest], len(rest)
                t_rev = t_end_s - len(rest) / self.rate_hz
                self._revolution(t_rev, float(rev.mean()), wall0)
            if self.state == "cutting" and self.ff is not None and self.ff.active:
                self._ff_step(t_end_s, wall0)
            # after the revolutions' feed steps: their bytes go out before the chatter window's
            # spectrum is computed (a chatter finding after them still holds or moves the spindle)
            if self.state == "cutting":
                self._chatter_check(f, t_end_s, wall0)

    def _on_block(self, first_sample: int, data: np.ndarray, wall0: float) -> None:
        if self.force_of is None:
            return
        n = data.shape[1]
        t = self.t0_s + (first_sample + np.arange(n)) / self.rate_hz
        f = self.force_of(np.asarray(data.T, float), t)
        self.push_forces(float(t[-1]) if n else self.clock(), f, wall0)

    # -- the loop --------------------------------------------------------------------------------
    def _revolution(self, t_s: float, force_n: float, wall0: float) -> None:
        s = self.s
        if self.state == "idle":
            self.state = "air"
        if force_n < s.air_force_n:
            if self.state == "cutting":
                self._note(t_s, f"cut ended: {force_n:.0f} N below air {s.air_force_n:.0f} N")
            self.state = "air"
            if self.ff is not None and (note := self.ff.on_revolution(t_s, force_n, False)):
                self._note(t_s, note)
            self.sat.end(t_s)
            self._chatter = None  # a new cut is judged afresh
            if self.feed_pct != 100 or self.spindle_pct != 100:
                self._reset(t_s, "air: overrides back to 100 %", wall0)
        else:
            if self.state != "cutting":
                self._note(t_s, f"cut started: {force_n:.0f} N")
            self.state = "cutting"
            self._saturated_now = False
            # the override this revolution was cut at: the last change's once GRBL ran it
            pct_ran: int | None = (self.feed_pct if t_s - self.rev_s >= self._applied_at_s
                                   else self._pct_was)  # fmt: skip
            if self.ff is not None:  # the changes' times known: at a limit all the revolution
                pct_ran = self.ff.ran_over(t_s - self.rev_s, t_s)  # None: it changed
                if note := self.ff.on_revolution(t_s, force_n, True):
                    self._note(t_s, note)
            if self.ff is not None and self.ff.active:
                pass  # the feed-forward sets the feed at each DAQ read (_ff_step)
            elif self._settle > 0 or t_s - self.rev_s < self._applied_at_s:  # or GRBL not at it
                self._settle = max(0, self._settle - 1)
            elif s.mode in ("feed", "both"):
                self._feed_step(t_s, force_n, wall0)
            if s.mode in ("feed", "both"):
                self._saturated_now = self.sat.track(t_s, force_n, pct_ran, s, self.rev_s)
        st = getattr(self.streamer, "last_status", None)
        self.trace.append(RevRecord(
            t_s, force_n, self.state, self.feed_pct, self.spindle_pct,
            getattr(self.streamer, "overrides", None) if self.streamer is not None else None,
            getattr(st, "feed_mm_min", None), self._saturated_now,
        ))  # fmt: skip

    def _feed_step(self, t_s: float, force_n: float, wall0: float) -> None:
        s = self.s
        err = force_n / s.target_force_n - 1.0
        if abs(err) * 100.0 <= s.dead_band_pct:
            return
        want = self.feed_pct * s.target_force_n / force_n
        lo = max(s.min_pct, self.feed_pct - s.slew_down_pct)
        hi = min(s.max_pct, self.feed_pct + s.slew_up_pct)
        new = int(round(min(max(want, lo), hi)))
        if new == self.feed_pct:
            return
        why = (f"force {force_n:.0f} N, target {s.target_force_n:.0f} N: feed "
               f"{self.feed_pct} -> {new} %")  # fmt: skip
        self._pct_was = self.feed_pct
        self._send(t_s, "feed", new, why, wall0)
        self._settle = s.settle_revs
        self._applied_at_s = t_s + APPLY_DELAY_S

    def _ff_step(self, t_s: float, wall0: float) -> None:
        want = self.ff.next_override(t_s, self.feed_pct, self.s, self.block_s) if self.ff else None
        if want is not None:  # the override the stock ahead asks for
            self._pct_was = self.feed_pct
            self._send(t_s, "feed", want[0], want[1], wall0)
            self._applied_at_s = t_s + APPLY_DELAY_S

    def _chatter_check(self, force_n: np.ndarray, t_s: float, wall0: float) -> bool:
        """The block's forces into the live chatter watch (at the speed cut now); True when it
        acted on a confirmed chatter."""
        s = self.s
        if t_s - (len(force_n) - 1) / self.rate_hz < self._new_speed_at_s:
            return False  # the old speed's samples are another process: not in the new window
        if self._chatter is None:
            rpm_now, st = self.rpm * self.spindle_pct / 100.0, self.chatter_settings
            self._chatter = ChatterWatch(self.channels, self.rate_hz, rpm_now, s.air_force_n, st,
                                         revolutions=s.chatter_revs)  # fmt: skip
        try:
            msg = self._chatter.push(force_n)
        except Exception:  # noqa: BLE001 - a window the detector cannot judge is no verdict
            return False
        v, seen = self._chatter.last, self._verdict
        self._verdict = v
        if msg is None:
            if v is not None and v is not seen and not v.chatter:
                self._cleared(t_s)
            return False
        if self.chatter_at_s is None:
            self.chatter_at_s = t_s
        what = msg
        if s.mode in ("spindle", "both") and self.lobes is not None:
            rpm_now = self.rpm * self.spindle_pct / 100.0
            pocket = nearest_pocket_rpm(self.lobes, self.rpm, self.depth_mm, s.min_pct, s.max_pct)
            if pocket is not None and abs(pocket - rpm_now) > 0.005 * self.rpm:
                pct = int(round(100.0 * pocket / self.rpm))
                self._send(t_s, "spindle", pct, f"{what}: spindle to the stable pocket "
                           f"{pocket:.0f} rpm ({pct} %)", wall0)  # fmt: skip
                self._chatter = None  # judge the new speed afresh, once GRBL turns at it
                self._settle = s.settle_revs
                self._applied_at_s = self._new_speed_at_s = t_s + APPLY_DELAY_S
                return True
            if pocket is not None:
                what += f": still at the pocket {pocket:.0f} rpm"
            else:
                what += f": no stable pocket within {s.min_pct}-{s.max_pct} %"
        elif s.mode != "feed":
            what += ": no lobes for the tool (no modes)"
        self._hold(what, t_s, wall0)
        return True

    def _cleared(self, t_s: float) -> None:
        """A steady window judged stable after chatter was found: said once."""
        if self.chatter_at_s is not None and self.chatter_cleared_s is None:
            self.chatter_cleared_s = t_s
            self._note(t_s, f"chatter cleared {t_s - self.chatter_at_s:.3f} s after it was found")

    # -- actions ---------------------------------------------------------------------------------
    def _send(self, t_s: float, kind: str, pct: int, why: str, wall0: float) -> None:
        cur = self.feed_pct if kind == "feed" else self.spindle_pct
        codes = _feed_codes(cur, pct) if kind == "feed" else _spindle_codes(cur, pct)
        if not self._write(codes, t_s, wall0):
            return
        if kind == "feed":
            self.feed_pct = pct
            if self.ff is not None:  # GRBL runs it after the segments already prepared
                self.ff.commanded((self.bytes_sent[-1][0] if codes else t_s) + APPLY_DELAY_S, pct)
        else:
            self.spindle_pct = pct
        lat = time.perf_counter() - wall0
        self.latencies_s.append(lat)
        self.decisions.append(Decision(t_s, kind, why, lat))
        t_w = self.bytes_sent[-1][0] if codes else t_s
        self._note(t_s, f"{why}; bytes {' '.join(f'0x{c:02X}' for c in codes)} at {t_w:.4f} s; "
                        f"{self._reported()}")  # fmt: skip

    def _write(self, codes: list[int], t_s: float, wall0: float) -> bool:
        """Each byte through the streamer's ``override`` with its run-clock time; a byte that
        cannot be written holds (safe by default). False when it held."""
        st = self.streamer
        for c in codes:
            if st is not None:
                if _stream_ended(st):
                    return self._ended(t_s)
                try:
                    st.override(c)
                except Exception as exc:  # noqa: BLE001 - a lost link: hold
                    if _stream_ended(st):  # the program ended (port closed) meanwhile
                        return self._ended(t_s)
                    self._hold(f"override 0x{c:02X} not sent ({exc})", t_s, wall0)
                    return False
            self.bytes_sent.append((self.clock(), c))
        return True

    def _ended(self, t_s: float) -> bool:
        """The stream is over (its record closed, the port closing): nothing to override and no
        fault; the DAQ's last blocks are still judged. Said once."""
        if not self.stream_over:
            self._note(t_s, "the stream has ended: no more overrides")
        self.stream_over = True
        return False

    def _reset(self, t_s: float, why: str, wall0: float) -> None:
        if self.feed_pct != 100:
            self._send(t_s, "feed", 100, why, wall0)
        if self.spindle_pct != 100:
            self._send(t_s, "spindle", 100, why, wall0)

    def _hold(self, why: str, t_s: float, wall0: float) -> None:
        """Feed hold first (the machine stops), then overrides back to 100 % (a resume must not
        start at an adapted feed), then the record."""
        st = self.streamer
        if st is not None:
            try:
                st.feed_hold()
            except Exception:  # noqa: BLE001 - nothing better to do from here: the run stops
                pass
        self.state = "hold"
        self.hold_reason = why
        self.sat.end(t_s)
        lat = time.perf_counter() - wall0
        self.latencies_s.append(lat)
        self.decisions.append(Decision(t_s, "hold", why, lat))
        if self.writer is not None:
            self.writer.event(rf.EV_PAUSE, f"adaptive: {why}: feed hold"[:200], time_s=t_s)
        if self.feed_pct != 100 or self.spindle_pct != 100:
            codes = _feed_codes(self.feed_pct, 100) + _spindle_codes(self.spindle_pct, 100)
            for c in codes:
                try:
                    if st is not None:
                        st.override(c)
                    self.bytes_sent.append((self.clock(), c))
                except Exception:  # noqa: BLE001 - held already; the reset is a courtesy
                    break
            self.feed_pct = self.spindle_pct = 100
            self._note(t_s, "held: overrides reset, bytes " + " ".join(f"0x{c:02X}" for c in codes))
        if self.on_hold is not None:
            self.on_hold(why)

    def _watchdog(self) -> None:
        while not self._stop.wait(0.002):
            with self._lock:
                if not self._armed or self.state == "hold" or self.stream_over:
                    continue
                now = self.clock()
                quiet = now - self._last_block_t
                if quiet > self.stall_s:
                    self._hold(f"force signal lost: no DAQ block for {quiet:.3f} s (limit "
                               f"{self.stall_s:.3f} s)", now, time.perf_counter())  # fmt: skip

    # -- record ----------------------------------------------------------------------------------
    def _reported(self) -> str:
        return reported_text(self.streamer, self.state)

    def _note(self, t_s: float, text: str) -> None:
        if self.writer is not None:
            self.writer.event(rf.EV_NOTE, f"adaptive: {text}"[:200], time_s=t_s)

    def live_status(self) -> AdaptiveStatus:
        """What the live console shows beside the force: target, last revolution's force, the
        overrides commanded and reported, the state (and why it held)."""
        return loop_status(self.s, self.trace, self.feed_pct, self.spindle_pct, self.state,
                           self.hold_reason)  # fmt: skip

    def summary(self) -> AdaptiveSummary:
        """Figures for the run's record and the bench."""
        return loop_summary(
            self.s, self.trace, self.rpm, decisions=len(self.decisions),
            override_bytes=len(self.bytes_sent), hold=self.hold_reason,
            latencies_s=self.latencies_s, cpu_s=self.cpu_s, feed_forward=self.ff is not None,
            chatter_at_s=self.chatter_at_s, chatter_cleared_s=self.chatter_cleared_s,
        )  # fmt: skip


def _stream_ended(streamer: Any) -> bool:
    """The streamer's record is closed: its program ended (ok or faulted) and its port closes."""
    ended = getattr(streamer, "sink_closed", None)
    return bool(ended()) if callable(ended) else False

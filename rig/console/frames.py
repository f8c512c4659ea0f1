"""What a connection sends: the live frames (:class:`_Client`: min/max bins per pixel, the status,
per-revolution readouts, the spectrum) and the traces of a zoom or a whole run (:func:`_trace`,
:func:`_live_trace`: min/max per pixel, or the samples themselves)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, cast

import numpy as np

from analysis.runs import file as rf
from rig.console.chatter import detected_peak, margin
from rig.console.forces import force_n
from rig.console.hub import Hub, _num
from rig.console.results import CutCase, LiveState, Margin, Peak
from rig.console.ring import RingReader

DEFAULT_PX, DEFAULT_WINDOW_S = 1000, 10.0
SPECTRUM_N = 4096  # samples per spectrum (0.5 s at 8 kHz: 2 Hz bins)
SPECTRUM_PX = 400


def bins_min_max(
    values: np.ndarray, sample: np.ndarray, per_bin: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Min and max per bin of ``per_bin`` samples (bin = sample // per_bin) of ``values``
    (n, c); returns (bin numbers (k,), min (c, k), max (c, k), position of the last bin's
    first row)."""
    if len(values) == 0:
        c = values.shape[1] if values.ndim == 2 else 0
        return np.zeros(0, np.int64), np.zeros((c, 0)), np.zeros((c, 0)), 0
    b = sample // per_bin
    starts = np.flatnonzero(np.r_[True, b[1:] != b[:-1]])
    lo = np.minimum.reduceat(values, starts, axis=0).T
    hi = np.maximum.reduceat(values, starts, axis=0).T
    return b[starts], lo, hi, int(starts[-1])


def _binned(t: np.ndarray, data: np.ndarray, px: int) -> dict[str, Any]:
    """Min and max per pixel of ``data`` (n, c) at times ``t``; when there are no more samples
    than two a pixel, the samples themselves (``raw``: a zoom shows what was recorded)."""
    n = len(data)
    if n <= 2 * max(px, 1):
        vals = np.round(data.T, 3).tolist() if n else [[] for _ in range(data.shape[1])]
        return {"t": np.round(t, 6).tolist(), "min": vals, "max": vals, "raw": True, "n": n}
    per = max(1, math.ceil(n / max(px, 1)))
    b, lo, hi, _ = bins_min_max(data, np.arange(n), per)
    return {"t": np.round(t[b * per], 5).tolist(), "min": np.round(lo, 2).tolist(),
            "max": np.round(hi, 2).tolist(), "raw": False, "n": n}  # fmt: skip


def _trace(path: Path, t0: float | None, t1: float | None, px: int) -> dict[str, Any]:
    meta = rf.load_run(path, samples=False, repair=False)
    base = meta.t0_s if math.isfinite(meta.t0_s) else 0.0
    start = None if t0 is None else max(0.0, t0 - base)
    stop = None if t1 is None else max(0.0, t1 - base)
    run = rf.load_run(path, start, stop, repair=False)
    data = run.force_n if run.force_n is not None else run.volts
    unit = "N" if run.force_n is not None else "V"
    out = _binned(np.asarray(run.time_s, float), np.asarray(data, float), px)
    return out | {"unit": unit, "channels": list(run.channel_names)}


def _live_trace(ring: RingReader, t0: float | None, t1: float | None, px: int) -> dict[str, Any]:
    """The live run's forces between ``t0`` and ``t1`` (run clock s; None: its start / now) as
    the ring still holds them (the whole run unless it outgrew the ring), binned as
    :func:`_binned`."""
    c = _Client(px, DEFAULT_WINDOW_S)
    _, c.meta = ring.get_json("meta")
    meta = c.meta or {}
    if not meta.get("rate_hz"):
        raise ValueError("no live run yet")
    rate, base = float(meta["rate_hz"]), float(meta.get("t0_s", 0.0))
    gen = ring.generation
    first = 0 if t0 is None else max(0, int((t0 - base) * rate))
    g, start, offset, rows = ring.rows_since(gen, max(0, first - ring.row_to_sample))
    if g != gen:
        raise ValueError("a new run began: ask again")
    t = base + (np.arange(start, start + len(rows)) + offset) / rate
    keep = np.ones(len(rows), bool) if t1 is None else t <= t1
    if t0 is not None:
        keep &= t >= t0
    data = c._force(rows[keep]) if keep.any() else np.zeros((0, rows.shape[1] if rows.ndim == 2
                                                                 else 0))  # fmt: skip
    return _binned(t[keep], data, px) | {"unit": "N", "channels": meta.get("channels", []),
                                         "run": meta.get("run"), "first_t": _num(t[0]) if len(t)
                                         else None}  # fmt: skip


class _Client:
    """One page's view of the ring: its cursor and bin width."""

    def __init__(self, px: int, window_s: float) -> None:
        self.px, self.window_s = px, window_s
        self.gen, self.cursor, self.meta_seq, self.status_seq = -1, 0, -1, -1
        self.meta: dict[str, Any] | None = None
        self.catch_up = True
        self.frames = 0
        self.runs_sig: tuple[Any, ...] | None = None
        self.live_state: LiveState | None = None
        self.last_rev = -1
        self.seen: tuple[int, int] = (-1, -1)
        self.written_ns = 0  # the ring's last block already timed on the page
        self.status: dict[str, Any] = {}
        self.trail_version, self.trail_n = -1, 0

    def news(self, hub: Hub) -> bool:
        """New samples (or a new run) in the ring since the last frame."""
        r = hub.ring
        return r is not None and (r.rows_written, r.generation) != self.seen

    def frame(self, hub: Hub) -> dict[str, Any]:
        self.frames += 1
        if hub.ring is not None:
            self.seen = (hub.ring.rows_written, hub.ring.generation)
        msg: dict[str, Any] = {"type": "frame", "n": self.frames}
        state = hub.live_state()
        if state != self.live_state:
            self.live_state = msg["live"] = state
        ring = hub.ring
        if ring is None:
            return msg
        seq = ring.seq("meta")
        if ring.generation != self.gen or seq != self.meta_seq:
            self.meta_seq, self.meta = ring.get_json("meta")
            self.gen = ring.generation
            rate = float((self.meta or {}).get("rate_hz", 0) or 0)
            self.cursor = max(0, ring.rows_written - int(self.window_s * rate))
            msg["meta"], msg["reset"] = self.meta, True
            self.catch_up = True
            self.last_rev = -1
        st_seq = ring.seq("status")
        if st_seq != self.status_seq:
            self.status_seq, msg["status"] = ring.get_json("status")
            self.status = msg["status"] or {}
        self._trail(hub, msg)
        if self.meta:
            # read before the rows: the newest block in this frame came no earlier (the latency
            # the page shows errs long, never short)
            written_ns = ring.written_ns
            bins = self._bins(ring)
            if bins is not None:
                if written_ns != self.written_ns:  # new samples in this frame: their latency
                    bins["written_ms"] = written_ns / 1e6
                    self.written_ns = written_ns
                msg["bins"] = bins
            if self.frames % 5 == 0:  # 5 times a second: a revolution at 300 rpm and up
                readouts = self._readouts(ring)
                if readouts is not None:
                    msg["readouts"] = readouts
                spectrum = self._spectrum(ring, hub)
                if spectrum is not None:
                    msg["spectrum"] = spectrum
        return msg

    def _trail(self, hub: Hub, msg: dict[str, Any]) -> None:
        """The executed path's new points (all of them again after a new run or a thinning)."""
        trail = hub.trail
        version, n = trail.version, len(trail.points)
        reset, points = trail.since(self.trail_version, self.trail_n)
        if reset or points:
            msg["trail"] = {"run": trail.run, "reset": reset, "points": points}
        self.trail_version, self.trail_n = version, n

    def _force(self, rows: np.ndarray) -> np.ndarray:
        """(n, c) N of the ring's rows (volts or codes): the run's zero and calibration."""
        return force_n(self.meta or {}, rows)

    def _rpm_now(self) -> float:
        """The spindle speed now: the controller's report (GRBL; the drip feed's program
        estimate), else the run's programmed speed."""
        meta = self.meta or {}
        told = (self.status.get("machine") or {}).get("spindle_rpm")
        if isinstance(told, int | float) and told > 0:
            return float(told)
        return abs(float(meta.get("spindle_rpm") or 0.0))

    def _spectrum(self, ring: RingReader, hub: Hub) -> dict[str, Any] | None:
        """Amplitude spectrum (N, Hann window) per channel of the newest SPECTRUM_N samples, up
        to the larger of 10 tooth-passing harmonics, 1 kHz and 1.25 x the predicted chatter
        frequency, at most SPECTRUM_PX points (the largest in each); the tooth-passing
        frequency; the lobes at this speed (:mod:`rig.console.chatter`) and the detected peak."""
        meta = self.meta or {}
        rate = float(meta.get("rate_hz") or 0.0)
        if rate <= 0 or meta.get("zero_v") is None:
            return None
        n = SPECTRUM_N
        g, _, _, rows = ring.rows_since(self.gen, max(0, ring.rows_written - n))
        if g != self.gen or len(rows) < n:
            return None
        f = self._force(rows)
        win = np.hanning(n)
        amp = np.abs(np.fft.rfft((f - f.mean(axis=0)) * win[:, None], axis=0)) * 2 / win.sum()
        freq = np.fft.rfftfreq(n, 1 / rate)
        rpm = self._rpm_now()
        teeth = meta.get("teeth") or 0
        tooth_hz = rpm / 60 * teeth if rpm and teeth else None
        stab = self._stability(hub, rpm)
        predicted = stab.get("predicted_hz") or 0.0
        top = min(rate / 2, max(1000.0, 10.5 * tooth_hz if tooth_hz else 0.0, 1.25 * predicted))
        k = int(np.searchsorted(freq, top))
        per = max(1, -(-k // SPECTRUM_PX))
        m = (k // per) * per
        peak = amp[:m].reshape(-1, per, amp.shape[1]).max(axis=1)
        return {"f_hz": np.round(freq[:m:per], 2).tolist(), "amp": np.round(peak.T, 3).tolist(),
                "df_hz": round(rate / n, 4), "tooth_hz": tooth_hz, "rpm": round(rpm, 1),
                "chatter_hz": stab.get("predicted_hz"), "stability": stab,
                "peak": self._peak(f, rate, rpm), "channels": meta.get("channels", []),
                "unit": "N"}  # fmt: skip

    def _stability(self, hub: Hub, rpm: float) -> Margin:
        meta = self.meta or {}
        # the ring's run meta (JSON): its "stability" entry is the campaign's CutCase
        case = cast(
            CutCase,
            meta.get("stability") or {"reason": "no lobes: the campaign gives no cut for them"},
        )
        lobes = None if "reason" in case or rpm <= 0 else hub.stability.get(meta.get("run"),
                                                                            case, rpm)  # fmt: skip
        return margin(lobes, case)

    @staticmethod
    def _peak(f: np.ndarray, rate: float, rpm: float) -> Peak:
        try:
            return detected_peak(f, rate, rpm)
        except Exception as exc:  # noqa: BLE001 - the spectrum shows without it
            return {"judged": False, "reason": f"no peak: {exc}"[:200]}

    def _readouts(self, ring: RingReader) -> dict[str, Any] | None:
        """Mean, peak and RMS of the last whole revolution per channel, N, as
        :func:`analysis.runs.per_revolution` cuts a run: revolution k is device samples
        round(k * spr) .. round((k + 1) * spr) - 1, spr = rate * 60 / rpm (the run's programmed
        speed). None until a new revolution is complete, or without a speed."""
        meta = self.meta or {}
        rpm = abs(float(meta.get("spindle_rpm") or 0.0))
        rate = float(meta.get("rate_hz") or 0.0)
        if rpm <= 0 or rate <= 0 or meta.get("zero_v") is None:
            return None  # before the zero: no forces to speak of
        spr = rate * 60.0 / rpm
        if spr < 8:
            return None
        w = ring.rows_written
        g, start, offset, rows = ring.rows_since(self.gen, max(0, w - int(2 * spr) - 2))
        if g != self.gen or len(rows) == 0:
            return None
        n_dev = start + offset + len(rows)  # device samples up to the newest
        k = int(n_dev // spr)
        while k >= 0 and round((k + 1) * spr) > n_dev:
            k -= 1
        if k <= self.last_rev or k < 0:
            return None
        a, b = round(k * spr) - offset - start, round((k + 1) * spr) - offset - start
        if a < 0:
            return None  # overwritten or a hole: the next one
        f = self._force(rows[a:b])
        self.last_rev = k
        t0 = float(meta.get("t0_s", 0.0))
        return {"run": meta.get("run"), "rev": k, "rpm": rpm,
                "t_s": round(t0 + round(k * spr) / rate, 5),
                "channels": meta.get("channels", []), "unit": "N",
                "mean": np.round(f.mean(axis=0), 2).tolist(),
                "peak": np.round(f.max(axis=0), 2).tolist(),
                "rms": np.round(np.sqrt((f * f).mean(axis=0)), 2).tolist()}  # fmt: skip

    def _bins(self, ring: RingReader) -> dict[str, Any] | None:
        meta = self.meta or {}
        rate = float(meta["rate_hz"])
        # A window on a (re)start, else at most half a second a frame: a view that fell behind
        # (or a DAQ faster than its rate, as in bench/bench_console.py) skips ahead.
        most = int(rate * (self.window_s if self.catch_up else 0.5)) + 1
        self.catch_up = False
        g, start, offset, rows = ring.rows_since(self.gen, self.cursor, most)
        if g != self.gen or len(rows) == 0 or rows.ndim != 2:
            return None
        force = self._force(rows)
        per = max(1, round(rate * self.window_s / self.px))
        sample = np.arange(start, start + len(rows)) + offset
        b, lo, hi, last = bins_min_max(force, sample, per)
        self.cursor = start + last  # the last bin may still grow: sent again next frame
        t0 = float(meta.get("t0_s", 0.0))
        return {"t": np.round(t0 + b * per / rate, 5).tolist(),
                "min": np.round(lo, 1).tolist(), "max": np.round(hi, 1).tolist()}  # fmt: skip

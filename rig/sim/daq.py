"""The simulated DAQ: the acquisition interface driven by a signal source instead of a device.

A source is any callable ``source(t0_s, n, rate_hz) -> ndarray (channels, n)`` giving amplifier
volts for the n samples starting at run-clock time t0_s; the simulated machining rig provides one,
:func:`sine_source` and :class:`PushedSource` are simple ones. Blocks reach the sink through the
same ``on_start`` / ``on_block`` / ``on_event`` calls as the NI driver, from the DAQ's own thread.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from analysis.runs import file as rf
from rig.daq import (
    SAMPLE_FORMAT_RAW,
    SAMPLE_FORMAT_VOLTS,
    Calibration,
    Daq,
    DaqError,
    DaqEvent,
    DaqInfo,
    DaqSink,
)
from rig.log.record import milling_force_source
from rig.sim.clock import SimClock

if TYPE_CHECKING:
    from analysis.config import RigConfig

Source = Callable[[float, int, float], np.ndarray]
ADC_BITS = 16


def sine_source(
    amplitude_v: Sequence[float] | float = 1.0,
    frequency_hz: Sequence[float] | float = 10.0,
    offset_v: Sequence[float] | float = 0.0,
    channels: int = 3,
) -> Source:
    """A source of sines, one per channel: v = offset + amplitude sin(2 pi f t)."""
    a = np.broadcast_to(np.asarray(amplitude_v, float), (channels,))[:, None]
    f = np.broadcast_to(np.asarray(frequency_hz, float), (channels,))[:, None]
    o = np.broadcast_to(np.asarray(offset_v, float), (channels,))[:, None]

    def source(t0_s: float, n: int, rate_hz: float) -> np.ndarray:
        t = t0_s + np.arange(n) / rate_hz
        return o + a * np.sin(2 * np.pi * f * t[None, :])

    return source


def ramp_source(channels: int = 3, slope_v_s: float = 0.01) -> Source:
    """Channel k gives ``(k + 1) * slope_v_s * t``: each sample's value tells its time, so tests
    can check that nothing was reordered or lost unseen."""
    scale = (np.arange(channels, dtype=float) + 1.0)[:, None] * slope_v_s

    def source(t0_s: float, n: int, rate_hz: float) -> np.ndarray:
        return scale * (t0_s + np.arange(n) / rate_hz)[None, :]

    return source


class PushedSource:
    """A source fed by another thread (``push(volts (c, n))``) and read in order by the SimDaq.

    When the DAQ needs samples that have not been pushed yet it gets ``fill_v`` and the shortfall
    is counted in ``underrun_samples`` (the simulated machine fell behind).
    """

    def __init__(self, channels: int, fill_v: float = 0.0) -> None:
        self.channels = channels
        self.fill_v = float(fill_v)
        self._chunks: deque[np.ndarray] = deque()
        self._lock = threading.Lock()
        self.underrun_samples = 0

    def push(self, volts: np.ndarray) -> None:
        v = np.asarray(volts, dtype=np.float64)
        if v.ndim != 2 or v.shape[0] != self.channels:
            raise DaqError(f"pushed block has shape {v.shape}: expected ({self.channels}, n)")
        with self._lock:
            self._chunks.append(v.copy())

    def __call__(self, t0_s: float, n: int, rate_hz: float) -> np.ndarray:
        out = np.full((self.channels, n), self.fill_v)
        got = 0
        with self._lock:
            while got < n and self._chunks:
                head = self._chunks[0]
                k = min(n - got, head.shape[1])
                out[:, got : got + k] = head[:, :k]
                got += k
                if k == head.shape[1]:
                    self._chunks.popleft()
                else:
                    self._chunks[0] = head[:, k:]
        self.underrun_samples += n - got
        return out


def adc_coefficients(channels: int, input_range_v: float) -> np.ndarray:
    """Scaling of an ideal 16-bit ADC over +-input_range_v: (c, 4), volts = c1 * code."""
    lsb = input_range_v / (2 ** (ADC_BITS - 1))
    coeff = np.zeros((channels, 4))
    coeff[:, 1] = lsb
    return coeff


class SimDaq(Daq):
    """Simulated continuous acquisition from a signal source.

    Parameters
    ----------
    source : ``source(t0_s, n, rate_hz) -> (c, n)`` volts.
    rate_hz, channels : sample rate per channel (Hz) and physical channel names.
    channel_names : names for the channels (default: the physical names).
    clock : the shared SimClock; its ``speed`` sets how much faster than real time blocks come.
        None: as fast as the sink takes them (benchmarks).
    read_interval_s : block length in seconds of samples (NI: about ten reads a second).
    seconds : stop by itself after this much simulated acquisition (None: until stop()).
    sample_format : "volts_float64" or "raw_int16" (an ideal 16-bit ADC over +-input_range_v).
    sim_overflow_at : device sample indices where a buffer overflow is injected.
    sim_overflow_samples : samples per channel lost at each injected overflow.
    sim_drop_blocks : block numbers (0-based) lost without the DAQ noticing (the logger must).
    sim_drift_v_s, sim_offset_v : per-channel linear drift (V/s) and offset (V) added to the source.
    sim_noise_v : rms of white noise added, V (seeded by ``sim_seed``).
    sim_saturate : clip at +-input_range_v like the ADC does, with a saturation event per block.

    Notes
    -----
    How it differs from the NI driver and a real device:

    - No hardware clock: time is the SimClock (or none); the delivered block length is exact,
      where DAQmx may hand back a slightly different amount per read.
    - An injected overflow loses exactly ``sim_overflow_samples`` and acquisition continues; a
      real -200279 error loses whatever the buffer overwrote before the driver recovered.
    - The ADC is ideal (linear, no offset, coefficient c1 = range / 32768); real devices have
      per-channel calibrated polynomials.
    - No anti-alias filter, settling, multiplexing skew between channels or input impedance.
    - Saturation clips at exactly +-input_range_v; real ADCs clip a little beyond the range.
    """

    def __init__(
        self,
        source: Source,
        *,
        rate_hz: float,
        channels: Sequence[str] = ("sim/ai0", "sim/ai1", "sim/ai2"),
        channel_names: Sequence[str] | None = None,
        clock: SimClock | None = None,
        read_interval_s: float = 0.1,
        seconds: float | None = None,
        sample_format: str = SAMPLE_FORMAT_VOLTS,
        input_range_v: float = 10.0,
        device: str = "sim",
        sim_overflow_at: Sequence[int] = (),
        sim_overflow_samples: int | None = None,
        sim_drop_blocks: Sequence[int] = (),
        sim_drift_v_s: Sequence[float] | float = 0.0,
        sim_offset_v: Sequence[float] | float = 0.0,
        sim_noise_v: float = 0.0,
        sim_seed: int = 0,
        sim_saturate: bool = True,
    ) -> None:
        super().__init__()
        if not rate_hz > 0:
            raise DaqError(f"rate_hz = {rate_hz}: must be > 0 (Hz)")
        if seconds is not None and not seconds > 0:
            raise DaqError(f"seconds = {seconds}: must be > 0 (s)")
        c = len(channels)
        block = max(1, int(round(rate_hz * read_interval_s)))
        coeff = adc_coefficients(c, input_range_v) if sample_format == SAMPLE_FORMAT_RAW else None
        self.info = DaqInfo(
            device=device,
            physical_channels=tuple(channels),
            channel_names=tuple(channel_names or channels),
            rate_hz=float(rate_hz),
            sample_format=sample_format,
            input_range_v=float(input_range_v),
            block_samples=block,
            scaling_coeff=coeff,
        )
        self.source = source
        self.clock = clock
        self.total_samples = None if seconds is None else int(round(seconds * rate_hz))
        self.sim_overflow_at = sorted(int(i) for i in sim_overflow_at)
        self.sim_overflow_samples = block if sim_overflow_samples is None else sim_overflow_samples
        self.sim_drop_blocks = frozenset(int(b) for b in sim_drop_blocks)
        self.sim_drift_v_s = np.broadcast_to(np.asarray(sim_drift_v_s, float), (c,))[:, None]
        self.sim_offset_v = np.broadcast_to(np.asarray(sim_offset_v, float), (c,))[:, None]
        self.sim_noise_v = float(sim_noise_v)
        self.sim_saturate = sim_saturate
        self._rng = np.random.default_rng(sim_seed)
        self._volts = np.empty((c, block))  # preallocated; reused for every block
        self._codes = np.empty((c, block), np.int16) if coeff is not None else None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        #: lockstep (the simulated rig's campaigns): the clock cannot pass the end of the block
        #: being read until the sink has taken it, so what the sink decides on a block (a
        #: suspender's feed hold) acts at that block's end in simulated time, however late the
        #: host ran this thread
        self.lockstep = False

    @classmethod
    def from_rig(
        cls,
        rig: RigConfig,
        *,
        rate_hz: float,
        seconds: float,
        channels: int | None = None,
        speed: float = 1.0,
        raw: bool = False,
        noise_v: float = 0.002,
        overflow_at: Sequence[int] = (),
        where: str = "configs/rig.toml",
        warn: Callable[[str], None] | None = None,
    ) -> SimDaq:
        """A simulated DAQ standing in for the rig's: ``channels`` (default the config's) of
        the synthetic milling force (:func:`rig.log.record.milling_force_source`) at ``rate_hz``
        for ``seconds``, ``speed`` simulated s per wall s (0: as fast as possible), int16 codes
        if ``raw``. Calibrated by the dynamometer when the channel counts match; otherwise
        ``warn(message)`` says the run is in volts. Sets :attr:`calibration`, :attr:`rig_meta`."""
        n = int(channels or len(rig.daq.channels))
        if not 1 <= n <= 64:
            raise DaqError(f"--channels = {n}: must be 1..64")
        cal = None
        if n == len(rig.dynamometer.channels):
            cal = Calibration.from_dynamometer(rig.dynamometer, n, where)
        elif warn is not None:
            has = len(rig.dynamometer.channels)
            warn(
                f"{n} channels but the dynamometer in {where} has {has}: recording volts "
                "without a calibration"
            )
        daq = cls(
            milling_force_source(cal, n),
            rate_hz=rate_hz,
            channels=tuple(f"sim/ai{i}" for i in range(n)),
            channel_names=cal.channel_names if cal else None,
            clock=SimClock(speed) if speed > 0 else None,
            read_interval_s=rig.daq.read_interval_s,
            seconds=seconds,
            sample_format=SAMPLE_FORMAT_RAW if raw else SAMPLE_FORMAT_VOLTS,
            input_range_v=rig.daq.input_range_v,
            sim_noise_v=noise_v,
            sim_overflow_at=overflow_at,
        )
        daq.calibration = cal
        daq.rig_meta = {"daq": "simulated", "dynamometer": rig.dynamometer.model}
        if cal is not None:
            daq.rig_meta["calibration_id"] = cal.calibration_id
        return daq

    @property
    def run_clock(self) -> Callable[[], float]:
        """The run clock (s) of a recording: the SimClock's, or 0 without one."""
        return self.clock.now if self.clock is not None else (lambda: 0.0)

    def start(self, sink: DaqSink) -> None:
        if self._thread is not None:
            raise DaqError("SimDaq.start: already started (one acquisition per object)")
        self._sink = sink
        t0 = self.clock.now() if self.clock is not None else 0.0
        self._t0_s = t0
        sink.on_start(self.info, t0)
        self._thread = threading.Thread(target=self._run, name="SimDaq", daemon=True)
        self._thread.start()

    def _lost_ranges(self) -> list[tuple[int, int]]:
        return [(k, k + self.sim_overflow_samples) for k in self.sim_overflow_at]

    def _run(self) -> None:
        info, sink = self.info, self._sink
        rate, block = info.rate_hz, info.block_samples
        lost = self._lost_ranges()
        i = 0  # device index of the next sample
        nblock = 0
        gate = f"daq-{id(self)}" if self.lockstep and hasattr(self.clock, "gate") else None
        try:
            while not self._stop.is_set():
                n = block if self.total_samples is None else min(block, self.total_samples - i)
                if n <= 0:
                    break
                t_start = self._t0_s + i / rate
                if gate is not None:
                    self.clock.gate(gate, self._t0_s + (i + n) / rate)  # type: ignore[union-attr]
                if self.clock is not None and not self.clock.sleep_until(
                    self._t0_s + (i + n) / rate, self._stop
                ):
                    break
                self._fill(t_start, i, n)
                if nblock not in self.sim_drop_blocks:
                    self._deliver(sink, i, n, lost)
                self.samples_acquired = i + n
                i += n
                nblock += 1
        except BaseException as exc:  # noqa: BLE001 - reported as an event and via .error
            self.error = exc
            sink.on_event(DaqEvent(rf.EV_FAULT, i, f"simulated DAQ failed: {exc}"))
        finally:
            if gate is not None:
                self.clock.gate(gate, None)  # type: ignore[union-attr]
            sink.on_event(DaqEvent(rf.EV_STOP, self.samples_acquired, "acquisition stopped"))
            self._done.set()

    def _fill(self, t_start: float, i: int, n: int) -> None:
        v = self._volts[:, :n]
        src = np.asarray(self.source(t_start, n, self.info.rate_hz), dtype=np.float64)
        if src.shape != (self.info.n_channels, n):
            raise DaqError(
                f"source returned shape {src.shape}: expected ({self.info.n_channels}, {n})"
            )
        np.copyto(v, src)
        if np.any(self.sim_offset_v):
            v += self.sim_offset_v
        if np.any(self.sim_drift_v_s):
            v += self.sim_drift_v_s * ((i + np.arange(n)) / self.info.rate_hz)[None, :]
        if self.sim_noise_v:
            v += self._rng.normal(0.0, self.sim_noise_v, v.shape)
        if self.sim_saturate:
            r = self.info.input_range_v
            over = np.abs(v) > r
            if over.any():
                first = int(np.argmax(over.any(axis=0)))
                self._sink.on_event(
                    DaqEvent(rf.EV_SATURATION, i + first,
                             f"{int(over.sum())} values beyond +-{r} V in this block")
                )  # fmt: skip
                np.clip(v, -r, r, out=v)
        if self._codes is not None:
            coeff = self.info.scaling_coeff
            assert coeff is not None  # codes are kept only with a scaling (__init__)
            lsb = coeff[0, 1]
            np.clip(np.rint(v / lsb), -32768, 32767, out=v)
            self._codes[:, :n] = v

    def _deliver(self, sink: DaqSink, i: int, n: int, lost: list[tuple[int, int]]) -> None:
        data = self._codes if self._codes is not None else self._volts
        keep_from = i
        for a, b in lost:
            if b <= i or a >= i + n:
                continue
            if a >= i:
                sink.on_event(DaqEvent(rf.EV_OVERFLOW, a, "simulated buffer overflow (-200279)"))
            if a > keep_from:
                sink.on_block(keep_from, data[:, keep_from - i : a - i])
                self.samples_delivered += a - keep_from
            keep_from = max(keep_from, min(b, i + n))
        if keep_from < i + n:
            sink.on_block(keep_from, data[:, keep_from - i : n])
            self.samples_delivered += i + n - keep_from

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join()

    def close(self) -> None:
        self.stop()

    def run(self, sink: DaqSink, timeout_s: float | None = None) -> None:
        """Start, wait until a finite run ends (``seconds``), stop. Convenience for scripts."""
        self.start(sink)
        self.wait(timeout_s)
        self.stop()
        if self.error is not None:
            raise DaqError(f"simulated DAQ failed: {self.error}") from self.error

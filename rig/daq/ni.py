"""NI-DAQmx driver: hardware-timed continuous acquisition through the real ``nidaqmx`` package.

One task reads all channels at ``rate_hz`` into a driver buffer of ``buffer_s`` seconds. An
every-N-samples event (N = rate x read_interval_s, about ten a second) reads exactly N samples per
channel through nidaqmx's stream readers into one preallocated (channels, N) array: int16 ADC codes
with ``AnalogUnscaledReader.read_int16`` (the device's per-channel ``ai_dev_scaling_coeff`` are
stored so no wrong scale can lose anything) or float64 volts with
``AnalogMultiChannelReader.read_many_sample``.

Continuity: the driver counts the samples it has read and compares that with the device's own
count (``in_stream.total_samp_per_chan_acquired``) after every read. The buffer is in
overwrite mode, so when reading falls behind by more than the buffer, DAQmx reports -200279
(samples no longer available) and the oldest samples are gone; the driver records an ``overflow``
event at the exact device index, repositions the read at the oldest sample still in the buffer
(``relative_to = FIRST_SAMPLE``, ``offset``) and carries on, so the lost stretch is a known
number of samples (a ``gap`` event in the run), never a silent splice. Any other DAQmx error
stops the acquisition and becomes a ``fault`` event and :attr:`NiDaq.error`.

Without the NI-DAQmx driver, nidaqmx raises ``DaqNotFoundError``, which is *not* a ``DaqError``;
both that and a missing device become :class:`DaqNotAvailableError` with what to install or set.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import nidaqmx
import nidaqmx.errors
import numpy as np
from nidaqmx.constants import (
    AcquisitionType,
    OverwriteMode,
    ReadRelativeTo,
    TerminalConfiguration,
    VoltageUnits,
)
from nidaqmx.error_codes import DAQmxErrors
from nidaqmx.stream_readers import AnalogMultiChannelReader, AnalogUnscaledReader

from analysis.config import DaqConfig, RigConfig
from analysis.runs import file as rf
from rig.daq.base import (
    SAMPLE_FORMAT_RAW,
    SAMPLE_FORMAT_VOLTS,
    Daq,
    DaqError,
    DaqEvent,
    DaqInfo,
    DaqNotAvailableError,
    DaqSink,
)
from rig.daq.calibration import Calibration

# Errors after which the buffer lost samples but the task can keep going.
OVERFLOW_CODES = frozenset(
    {
        DAQmxErrors.SAMPLES_NO_LONGER_AVAILABLE.value,  # -200279
        DAQmxErrors.INPUT_FIFO_OVERFLOW.value,  # -200010
        DAQmxErrors.INPUT_FIFO_OVERFLOW_2.value,  # -200361
        DAQmxErrors.ADC_OVERRUN.value,  # -200019
    }
)
DEVICE_MISSING_CODES = frozenset(
    {
        DAQmxErrors.INVALID_DEVICE_ID.value,  # -200220
        DAQmxErrors.PHYSICAL_CHAN_DOES_NOT_EXIST.value,  # -200170
        DAQmxErrors.DEV_CANNOT_BE_ACCESSED.value,  # -201003
    }
)

HOW_TO_CONFIGURE = (
    "Install NI-DAQmx (Windows: the NI-DAQmx runtime; Linux: `python -m nidaqmx installdriver` "
    "on a supported distribution), connect the device, find its name with NI MAX or "
    "`nidaqmx.system.System.local().devices`, and set [daq] device and channels in "
    "configs/rig.toml (`cutlab daq record --rig FILE` reads another file; a campaign's [daq] "
    "table overrides it). Without hardware, record with `cutlab daq record --sim`, or run the "
    'campaign with rig = "sim".'
)


def _known_devices() -> str:
    try:
        names = [d.name for d in nidaqmx.system.System.local().devices]
    except Exception:  # noqa: BLE001 - only for the message
        return "unknown"
    return ", ".join(names) or "none"


class NiDaq(Daq):
    """Continuous acquisition on an NI device; same interface as :class:`rig.sim.daq.SimDaq`.

    Parameters
    ----------
    config : the [daq] section of the rig config (device, channels, rate_hz, input_range_v,
        terminal_config, buffer_s, read_interval_s, raw).
    channel_names : names for the channels (default: the physical channel names).
    clock : run clock; its value when the task starts is t0_s (monotonic s).
    task_factory, unscaled_reader, scaled_reader : the nidaqmx classes (tests inject autospecs).
    """

    def __init__(
        self,
        config: DaqConfig,
        channel_names: Sequence[str] | None = None,
        *,
        clock: Callable[[], float] = time.monotonic,
        task_factory: Callable[[], Any] = nidaqmx.Task,
        unscaled_reader: Callable[[Any], Any] = AnalogUnscaledReader,
        scaled_reader: Callable[[Any], Any] = AnalogMultiChannelReader,
    ) -> None:
        super().__init__()
        self.config = config
        self.clock = clock
        self._task_factory = task_factory
        self._unscaled_reader = unscaled_reader
        self._scaled_reader = scaled_reader
        self._names = tuple(channel_names or config.channels)
        if len(self._names) != len(config.channels):
            raise DaqError(
                f"{len(self._names)} channel names ({', '.join(self._names)}) for "
                f"{len(config.channels)} DAQ channels ({', '.join(config.channels)})"
            )
        self.block_samples = max(1, int(round(config.rate_hz * config.read_interval_s)))
        self.buffer_samples = max(
            2 * self.block_samples, int(round(config.rate_hz * config.buffer_s))
        )
        self.info = DaqInfo(  # start() sets the sample format and the device's coefficients
            device=config.device,
            physical_channels=tuple(config.channels),
            channel_names=self._names,
            rate_hz=float(config.rate_hz),
            sample_format=SAMPLE_FORMAT_VOLTS,
            input_range_v=float(config.input_range_v),
            block_samples=self.block_samples,
        )
        self._task: Any = None
        self._reader: Any = None
        self._flat: np.ndarray | None = None  # one preallocated block, viewed as (c, n)
        self._sink: DaqSink | None = None
        self._lock = threading.Lock()
        self._running = False
        self._stopped = False
        self.samples_read = 0  # device index of the next sample to read

    @classmethod
    def from_rig(
        cls,
        rig: RigConfig,
        *,
        rate_hz: float | None = None,
        channels: int | None = None,
        where: str = "configs/rig.toml",
    ) -> NiDaq:
        """The NI DAQ of a rig config's [daq] (read from ``where``), with ``rate_hz`` (Hz per
        channel) and the first ``channels`` channels instead of the config's when given, the
        dynamometer's calibration and the rig metadata to store (:attr:`rig_meta`)."""
        cfg = rig.daq
        if rate_hz:
            cfg = cfg.model_copy(update={"rate_hz": float(rate_hz)})
        if channels:
            if channels > len(cfg.channels):
                raise DaqError(
                    f"--channels = {channels}: {where} lists only {len(cfg.channels)} daq.channels"
                )
            cfg = cfg.model_copy(update={"channels": cfg.channels[:channels]})
        cal = Calibration.from_dynamometer(rig.dynamometer, len(cfg.channels), where)
        daq = cls(cfg, cal.channel_names)
        daq.calibration = cal
        daq.rig_meta = {"daq": cfg.model_dump(), "dynamometer": rig.dynamometer.model,
                        "calibration_id": cal.calibration_id}  # fmt: skip
        return daq

    @property
    def run_clock(self) -> Callable[[], float]:
        """The run clock (monotonic s) of the recording."""
        return self.clock

    # -- setup ---------------------------------------------------------------------------------

    def _open_task(self) -> Any:
        try:
            return self._task_factory()
        except nidaqmx.errors.DaqNotFoundError as exc:  # not a DaqError subclass
            raise DaqNotAvailableError(
                f"NI-DAQmx driver not found ({exc}). {HOW_TO_CONFIGURE}"
            ) from None
        except nidaqmx.errors.DaqNotSupportedError as exc:
            raise DaqNotAvailableError(
                f"NI-DAQmx is not supported on this platform ({exc}). {HOW_TO_CONFIGURE}"
            ) from None

    def _configure(self, task: Any) -> DaqInfo:
        cfg = self.config
        r = float(cfg.input_range_v)
        for phys, name in zip(cfg.channels, self._names):
            task.ai_channels.add_ai_voltage_chan(
                phys,
                name_to_assign_to_channel=name,
                terminal_config=TerminalConfiguration[cfg.terminal_config],
                min_val=-r,
                max_val=r,
                units=VoltageUnits.VOLTS,
            )
        task.timing.cfg_samp_clk_timing(
            float(cfg.rate_hz),
            sample_mode=AcquisitionType.CONTINUOUS,
            samps_per_chan=self.buffer_samples,
        )
        task.in_stream.input_buf_size = self.buffer_samples
        # Overwrite mode: falling behind loses the oldest samples, which we can count exactly,
        # instead of stopping the task.
        task.in_stream.over_write = OverwriteMode.OVERWRITE_UNREAD_SAMPLES
        c = len(cfg.channels)
        if cfg.raw:
            coeff = [list(task.ai_channels[name].ai_dev_scaling_coeff) for name in self._names]
            k = max(len(x) for x in coeff)
            sc = np.zeros((c, k))
            for i, x in enumerate(coeff):
                sc[i, : len(x)] = x
            self._reader = self._unscaled_reader(task.in_stream)
            self._flat = np.zeros(c * self.block_samples, dtype=np.int16)
            fmt = SAMPLE_FORMAT_RAW
        else:
            sc = None
            self._reader = self._scaled_reader(task.in_stream)
            self._flat = np.zeros(c * self.block_samples, dtype=np.float64)
            fmt = SAMPLE_FORMAT_VOLTS
        task.register_every_n_samples_acquired_into_buffer_event(
            self.block_samples, self._on_every_n_samples
        )
        return replace(self.info, sample_format=fmt, scaling_coeff=sc)

    def start(self, sink: DaqSink) -> None:
        if self._task is not None:
            raise DaqError("NiDaq.start: already started (one acquisition per object)")
        task = self._open_task()
        self._task = task
        try:
            self.info = self._configure(task)
            self._sink = sink
            t0 = self.clock()
            sink.on_start(self.info, t0)  # before the first every-N callback can fire
            self._running = True
            task.start()
        except nidaqmx.errors.DaqError as exc:
            self._running = False
            self._close_task()
            if exc.error_code in DEVICE_MISSING_CODES:
                raise DaqNotAvailableError(
                    f"NI device '{self.config.device}' or channels {list(self.config.channels)} "
                    f"not found (DAQmx {exc.error_code}); devices present: {_known_devices()}. "
                    f"{HOW_TO_CONFIGURE}"
                ) from None
            raise DaqError(f"cannot start the DAQ task: {exc}") from None

    # -- acquisition (DAQmx callback thread) ---------------------------------------------------

    def _on_every_n_samples(
        self, task_handle: Any, every_n_samples_event_type: int, number_of_samples: int, data: Any
    ) -> int:
        """DAQmx callback: read one block. Must return 0 and must not raise (ctypes drops it)."""
        try:
            with self._lock:
                # Read every whole block waiting (more than one after a late callback), so a
                # hiccup does not leave a permanent backlog.
                stream = self._task.in_stream
                for _ in range(self.buffer_samples // self.block_samples + 2):
                    if not self._running:
                        break
                    waiting = int(stream.total_samp_per_chan_acquired) - self.samples_read
                    if waiting < self.block_samples:
                        break
                    self._read(self.block_samples)
        except BaseException as exc:  # noqa: BLE001 - a callback cannot raise into DAQmx
            self._fail(exc)
        return 0

    def _view(self, n: int) -> np.ndarray:
        """(c, n) C-contiguous view of the preallocated block (the readers need contiguity)."""
        c = len(self._names)
        return self._flat[: c * n].reshape(c, n)  # type: ignore[index]

    def _read_into(self, n: int) -> int:
        buf = self._view(n)
        timeout_s = max(1.0, 4 * self.config.read_interval_s)
        if self.info.sample_format == SAMPLE_FORMAT_RAW:
            return int(
                self._reader.read_int16(buf, number_of_samples_per_channel=n, timeout=timeout_s)
            )
        return int(
            self._reader.read_many_sample(buf, number_of_samples_per_channel=n, timeout=timeout_s)
        )

    def _read(self, n: int) -> None:
        """Read n samples per channel at the current position and hand them to the sink."""
        sink = self._sink
        try:
            got = self._read_into(n)
        except nidaqmx.errors.DaqError as exc:
            if exc.error_code not in OVERFLOW_CODES:
                raise
            got = self._recover(exc, n)
        if got > 0:
            data = self._view(n)[:, :got]
            if data.dtype == np.int16:
                self._check_saturation(data)
            sink.on_block(self.samples_read, data)  # type: ignore[union-attr]
            self.samples_read += got
            self.samples_delivered += got
            self.samples_acquired = self.samples_read
        # Continuity: the device can never be behind us, and never more than a buffer ahead.
        acquired = int(self._task.in_stream.total_samp_per_chan_acquired)
        if acquired < self.samples_read:
            raise DaqError(
                f"device reports {acquired} samples acquired but {self.samples_read} were read"
            )

    def _check_saturation(self, codes: np.ndarray) -> None:
        """A code at the ends of the int16 range means the input was at or beyond the range."""
        at_limit = (codes == np.iinfo(np.int16).max) | (codes == np.iinfo(np.int16).min)
        if at_limit.any():
            first = int(np.argmax(at_limit.any(axis=0)))
            self._sink.on_event(  # type: ignore[union-attr]
                DaqEvent(rf.EV_SATURATION, self.samples_read + first,
                         f"{int(at_limit.sum())} codes at the ADC limits in this block")
            )  # fmt: skip

    def _recover(self, exc: nidaqmx.errors.DaqError, n: int) -> int:
        """After an overflow: record it, jump to the oldest sample still buffered, read there."""
        stream = self._task.in_stream
        acquired = int(stream.total_samp_per_chan_acquired)
        # Leave one block of margin so the device does not overwrite where we resume.
        resume = max(self.samples_read, acquired - self.buffer_samples + self.block_samples)
        self._sink.on_event(  # type: ignore[union-attr]
            DaqEvent(rf.EV_OVERFLOW, self.samples_read,
                     f"DAQmx {exc.error_code}: buffer overflow; {acquired} acquired, "
                     f"{self.samples_read} read; resuming at sample {resume}")
        )  # fmt: skip
        stream.relative_to = ReadRelativeTo.FIRST_SAMPLE
        stream.offset = resume
        try:
            got = self._read_into(n)
        finally:
            stream.relative_to = ReadRelativeTo.CURRENT_READ_POSITION
            stream.offset = 0
        self.samples_read = resume  # the sink sees the hole and records the gap
        return got

    def _fail(self, exc: BaseException) -> None:
        self.error = exc
        self._running = False
        if self._sink is not None:
            self._sink.on_event(DaqEvent(rf.EV_FAULT, self.samples_read, f"DAQ error: {exc}"[:200]))
        self._done.set()

    # -- stop ----------------------------------------------------------------------------------

    def stop(self) -> None:
        """Stop: unregister the event, read what the device acquired so far, stop the task."""
        task = self._task
        if task is None or self._stopped:
            return
        self._stopped = True
        with self._lock:
            was_running, self._running = self._running, False
            try:
                if was_running:
                    task.register_every_n_samples_acquired_into_buffer_event(
                        self.block_samples, None
                    )
                    acquired = int(task.in_stream.total_samp_per_chan_acquired)
                    while self.samples_read < acquired:
                        self._read(min(self.block_samples, acquired - self.samples_read))
                task.stop()
            except nidaqmx.errors.DaqError as exc:
                self._fail(exc)
            if self._sink is not None and was_running:
                self._sink.on_event(DaqEvent(rf.EV_STOP, self.samples_read, "acquisition stopped"))
        self._done.set()

    def _close_task(self) -> None:
        if self._task is not None:
            try:
                self._task.close()
            except nidaqmx.errors.DaqError:
                pass
            self._task = None

    def close(self) -> None:
        if self._task is not None:
            self.stop()
            self._close_task()

"""The acquisition interface shared by the NI-DAQmx driver and the simulated DAQ.

A DAQ acquires ``c`` channels continuously at ``rate_hz`` and hands every block it reads to a sink
(normally :class:`rig.log.writer.RunWriter`) from its own thread::

    sink.on_start(info, t0_s)          once, t0_s = run-clock time of device sample 0
    sink.on_block(first_sample, data)  data (c, n): int16 ADC codes or float64 volts, valid only
                                       during the call (the DAQ reuses its preallocated buffer)
    sink.on_event(event)               overflow, fault, saturation, stop ...

``first_sample`` is the device's own sample index, so a block that never arrives leaves a visible
hole; the DAQ reports what it knows (an overflow, an error) and the sink records the hole.
"""

from __future__ import annotations

import math
import threading
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from analysis.runs.file import SAMPLE_FORMAT_RAW as SAMPLE_FORMAT_RAW  # the run file's names
from analysis.runs.file import SAMPLE_FORMAT_VOLTS as SAMPLE_FORMAT_VOLTS
from rig.errors import RigError

if TYPE_CHECKING:
    from rig.daq.calibration import Calibration


class DaqError(RigError):
    """The DAQ failed, or is configured in a way the hardware (or the simulation) cannot do."""


class DaqNotAvailableError(DaqError):
    """No NI-DAQmx driver or no device: the message says what is missing and how to set it up."""


@dataclass(frozen=True)
class DaqInfo:
    """What a DAQ acquires. scaling_coeff: (c, k) volts = sum_j coeff[:, j] code^j (raw only)."""

    device: str
    physical_channels: tuple[str, ...]
    channel_names: tuple[str, ...]
    rate_hz: float
    sample_format: str  # SAMPLE_FORMAT_RAW or SAMPLE_FORMAT_VOLTS
    input_range_v: float
    block_samples: int  # samples per channel in each on_block (the last one may be shorter)
    scaling_coeff: np.ndarray | None = None

    def __post_init__(self) -> None:
        c = len(self.physical_channels)
        if len(self.channel_names) != c:
            raise DaqError(
                f"{len(self.channel_names)} channel names for {c} physical channels "
                f"({', '.join(self.physical_channels)})"
            )
        if self.sample_format not in (SAMPLE_FORMAT_RAW, SAMPLE_FORMAT_VOLTS):
            raise DaqError(f"sample_format = {self.sample_format!r}: expected raw_int16 or volts")
        if self.sample_format == SAMPLE_FORMAT_RAW:
            sc = None if self.scaling_coeff is None else np.asarray(self.scaling_coeff, float)
            if sc is None or sc.ndim != 2 or sc.shape[0] != c:
                raise DaqError(
                    f"raw samples need scaling coefficients of shape ({c}, k); got "
                    f"{None if sc is None else sc.shape}"
                )
            object.__setattr__(self, "scaling_coeff", sc)
        if not self.rate_hz > 0 or self.block_samples < 1:
            raise DaqError(f"rate_hz = {self.rate_hz}, block_samples = {self.block_samples}")

    @property
    def n_channels(self) -> int:
        return len(self.physical_channels)

    @property
    def dtype(self) -> np.dtype:
        return np.dtype(np.int16 if self.sample_format == SAMPLE_FORMAT_RAW else np.float64)


@dataclass(frozen=True)
class DaqEvent:
    """Something the DAQ saw: kind is one of analysis.runs.file.EVENT_KINDS.

    sample : device sample index where it happened; lost : samples per channel it cost (0 if the
    DAQ does not know; the sink measures holes itself); time_s : run clock (NaN: from sample).
    """

    kind: str
    sample: int
    message: str = ""
    lost: int = 0
    time_s: float = math.nan


class DaqSink(Protocol):
    """Receives what a DAQ acquires (see the module docstring for the call order)."""

    def on_start(self, info: DaqInfo, t0_s: float) -> None: ...

    def on_block(self, first_sample: int, data: np.ndarray) -> None: ...

    def on_event(self, event: DaqEvent) -> None: ...


class Daq(ABC):
    """One continuous acquisition: ``start(sink)``, then ``stop()``; ``close()`` frees it."""

    info: DaqInfo
    #: set by a driver's ``from_rig``: the calibration and rig metadata a recording stores
    calibration: Calibration | None = None
    rig_meta: dict[str, Any] | None = None

    def __init__(self) -> None:
        self._done = threading.Event()
        self.error: BaseException | None = None
        self.samples_delivered = 0  # per channel, handed to the sink
        self.samples_acquired = 0  # per channel, on the device clock (delivered + lost)

    @abstractmethod
    def start(self, sink: DaqSink) -> None:
        """Begin acquiring; blocks go to ``sink`` from the DAQ's thread."""

    @abstractmethod
    def stop(self) -> None:
        """Stop acquiring, deliver what was acquired, emit a stop event. Idempotent."""

    @abstractmethod
    def close(self) -> None:
        """Release the device (stops first if needed). Idempotent."""

    def wait(self, timeout_s: float | None = None) -> bool:
        """Wait until the acquisition ends by itself (finite sim run, fatal error)."""
        return self._done.wait(timeout_s)

    @property
    def done(self) -> bool:
        return self._done.is_set()

    def __enter__(self) -> Daq:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

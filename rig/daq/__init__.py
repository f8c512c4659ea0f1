"""Dynamometer acquisition: one interface (:class:`Daq`), the NI-DAQmx driver and the volts-to-N
calibration.

- :mod:`rig.daq.base` — the interface: :class:`Daq`, :class:`DaqSink`, :class:`DaqInfo`,
  :class:`DaqEvent`, errors.
- :mod:`rig.daq.ni` — :class:`NiDaq` on the ``nidaqmx`` package (hardware-timed, every-N-samples
  reads into a preallocated array, continuity checked against the device's sample count).
- :mod:`rig.daq.calibration` — :class:`Calibration`: volts to newtons (matrix, offsets, gains).

The simulated DAQ is :class:`rig.sim.SimDaq` (simulated backends live in :mod:`rig.sim`).
`NiDaq` is not re-exported here: importing it loads ``nidaqmx``.
"""

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

__all__ = [
    "Calibration",
    "SAMPLE_FORMAT_RAW",
    "SAMPLE_FORMAT_VOLTS",
    "Daq",
    "DaqError",
    "DaqEvent",
    "DaqInfo",
    "DaqNotAvailableError",
    "DaqSink",
]

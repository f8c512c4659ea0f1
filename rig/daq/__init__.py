"""Dynamometer acquisition: one interface (:class:`Daq`), the NI-DAQmx driver and a simulated DAQ.

- :mod:`rig.daq.base` — the interface: :class:`Daq`, :class:`DaqSink`, :class:`DaqInfo`,
  :class:`DaqEvent`, errors.
- :mod:`rig.daq.ni` — :class:`NiDaq` on the ``nidaqmx`` package (hardware-timed, every-N-samples
  reads into a preallocated array, continuity checked against the device's sample count).
- :mod:`rig.sim.daq` — :class:`SimDaq` driven by a signal source, with ``sim_`` fault knobs.
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
from rig.sim.daq import PushedSource, SimDaq, ramp_source, sine_source

__all__ = [
    "SAMPLE_FORMAT_RAW",
    "SAMPLE_FORMAT_VOLTS",
    "Daq",
    "DaqError",
    "DaqEvent",
    "DaqInfo",
    "DaqNotAvailableError",
    "DaqSink",
    "PushedSource",
    "SimDaq",
    "ramp_source",
    "sine_source",
]

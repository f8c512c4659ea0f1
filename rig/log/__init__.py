"""Recording: the HDF5 run writer (crash-safe, flushed in steps) and ``record`` (a DAQ into a run
file for N seconds).
"""

from rig.log.record import record
from rig.log.writer import RunWriter, RunWriterError, WriterStats

__all__ = ["RunWriter", "RunWriterError", "WriterStats", "record"]

"""Recording: the HDF5 run writer (crash-safe, flushed in steps) and ``record`` (a DAQ into a run
file for N seconds; ``plan_recording`` + ``record_rig`` as ``cutlab daq record`` does it).
"""

from rig.log.record import RecordPlan, RecordResult, plan_recording, record, record_rig
from rig.log.writer import RunWriter, RunWriterError, WriterStats

__all__ = [
    "RecordPlan",
    "RecordResult",
    "RunWriter",
    "RunWriterError",
    "WriterStats",
    "plan_recording",
    "record",
    "record_rig",
]

"""Recording: the HDF5 run writer (crash-safe, flushed in steps, stopping before its disk fills;
``free_space_problem`` checks room before a recording) and ``record`` (a DAQ into a run
file for N seconds; ``plan_recording`` + ``record_rig`` as ``cutlab daq record`` does it);
``import_exports`` (DynoWare / CSV exports into run files, ``cutlab data import``).
"""

from rig.log._file import disk_full_reason
from rig.log.importer import import_exports, write_export_run
from rig.log.record import RecordPlan, RecordResult, plan_recording, record, record_rig
from rig.log.writer import RunWriter, RunWriterError, WriterStats, free_space_problem

__all__ = [
    "RecordPlan",
    "RecordResult",
    "RunWriter",
    "RunWriterError",
    "WriterStats",
    "disk_full_reason",
    "free_space_problem",
    "import_exports",
    "plan_recording",
    "record",
    "record_rig",
    "write_export_run",
]

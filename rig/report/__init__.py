"""A campaign's report folder: the runs table, the configured analysis and its plots."""

from rig.report.base import Report
from rig.report.write import write_report

__all__ = ["Report", "write_report"]

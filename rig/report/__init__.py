"""A campaign's report folder: the runs table, the configured analysis and its plots; and
``cutlab demo`` (:func:`run_demo`: the face-milling campaign on the simulated rig, reported)."""

from rig.report.base import Report
from rig.report.demo import DEMO_CAMPAIGN, DemoResult, run_demo
from rig.report.write import write_report

__all__ = ["DEMO_CAMPAIGN", "DemoResult", "Report", "run_demo", "write_report"]

"""rig.report.base."""

"""analysis.runs."""

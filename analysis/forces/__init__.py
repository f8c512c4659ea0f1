"""analysis.forces."""

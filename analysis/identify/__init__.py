"""analysis.identify."""

"""analysis.modal.hammer."""

"""planning.stock."""

"""planning.surface."""

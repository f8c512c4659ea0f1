"""planning.feed."""

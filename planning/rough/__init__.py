"""planning.rough."""

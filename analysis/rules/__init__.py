"""analysis.rules.rule."""

"""Planning's branch of the exception tree."""

from __future__ import annotations

from analysis.errors import CutlabError


class PlanningError(CutlabError, ValueError):
    """A planning input (surface, part, tool, rule, program) cannot be used as given."""

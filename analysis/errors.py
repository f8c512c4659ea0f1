"""The root of cutlab's exception tree.

Every error a user can cause derives from :class:`CutlabError`; the ``cutlab`` command prints its
message (which names the file, line, field, value and the expected unit or range) and exits with
status 2 instead of showing a traceback. Each package adds its own branch: ``ConfigError`` and
``AnalysisError`` here, ``PlanningError``/``NCError`` in ``planning``, ``RigError`` in ``rig``.
"""

from __future__ import annotations


class CutlabError(Exception):
    """Base of every error caused by input, configuration or hardware rather than a bug."""


class ConfigError(CutlabError, ValueError):
    """A config file is missing, malformed, or has a field outside its allowed range."""


class AnalysisError(CutlabError, ValueError):
    """Data given to an analysis cannot be used (wrong shape, mixed units, no cutting, ...)."""

"""Rig's branch of the exception tree."""

from __future__ import annotations

from analysis.errors import CutlabError


class RigError(CutlabError, RuntimeError):
    """Hardware, a serial link, a DAQ or a run file failed or is configured wrongly."""

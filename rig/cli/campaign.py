"""`cutlab campaign` commands (placeholder: registers nothing until its issue lands)."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""

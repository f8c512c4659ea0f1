"""What every config module shares: where the configs are, and the field helper."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from pydantic import Field

REPO_ROOT = Path(__file__).resolve().parents[2]


def config_dir() -> Path:
    """The folder holding cutlab's config files."""
    return Path(os.environ.get("CUTLAB_CONFIG_DIR", REPO_ROOT / "configs"))


def mm_field(desc: str = "mm", **kw: Any) -> Any:
    """A pydantic field with its unit (or what it is) as its description."""
    return Field(description=desc, **kw)

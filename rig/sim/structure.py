"""The twin's own structure (``structure.toml``): the tool-tip modes of the tool assemblies the
simulated rig cuts with, its physical truth, apart from the tool catalogue.

The catalogue's ``[[tools.NAME.modes]]`` are what a tap test measures (issue 28): on the simulated
rig, :mod:`rig.sim.tap` taps these modes and ``cutlab analyze modal --save`` identifies them, and
the catalogue records that provenance. The twin never reads the catalogue's modes: a tool whose
assembly is not described here cuts quasi-statically (no regeneration), whatever its catalogue
entry says.
"""

from __future__ import annotations

import tomllib
from functools import cache
from pathlib import Path
from typing import Any

from analysis.config import EndMill, FaceMill, ToolMode, get_tool
from analysis.errors import ConfigError
from analysis.forces import ENDMILL

__all__ = ["STRUCTURE_FILE", "twin_modes"]

STRUCTURE_FILE = Path(__file__).with_name("structure.toml")

#: Catalogue fields that are not the assembly's physics (names, measured modes, limits).
_NOT_PHYSICAL = {"description", "modes", "max_chip_mm", "overload_gain", "deflection_tol_mm"}


def _physical(tool: EndMill | FaceMill) -> dict[str, Any]:
    return tool.model_dump(exclude=_NOT_PHYSICAL)


@cache
def _assemblies() -> tuple[tuple[dict[str, Any], tuple[ToolMode, ...]], ...]:
    """(the catalogue assembly's physical fields, the twin's modes) per entry."""
    try:
        data = tomllib.loads(STRUCTURE_FILE.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError(f"{STRUCTURE_FILE}: {exc}") from None
    out = []
    for name, entry in data.get("tools", {}).items():
        try:
            modes = tuple(ToolMode(**m) for m in entry["modes"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"{STRUCTURE_FILE}: tools.{name}.modes: {exc}") from None
        out.append((_physical(get_tool(name)), modes))
    return tuple(out)


def twin_modes(tool: EndMill | FaceMill) -> tuple[ToolMode, ...]:
    """The twin's tool-tip modes for ``tool``'s assembly; () when the twin has none (face mills:
    the twin cuts them quasi-statically)."""
    if not ENDMILL.describes(tool):
        return ()
    key = _physical(tool)
    return next((modes for phys, modes in _assemblies() if phys == key), ())

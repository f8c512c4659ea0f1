"""Validated TOML configs shared by every cutlab package.

Machines, tools, materials, dynamometers and DAQs are described in TOML files under ``configs/``.
They live here, in the lowest package, because all three packages read them. Every model is a
frozen pydantic model with ``extra="forbid"`` (:mod:`analysis.validation`): an unknown key is an
error, and every error names the file, the line, the dotted field, the value given and the expected
unit or range.

Units follow DESIGN.md: mm, mm/min, rpm, N, N/mm, N/mm^2, s, Hz and degrees in configs.

Where the configs are: ``$CUTLAB_CONFIG_DIR`` if set, else the ``configs/`` folder of the checkout
(cutlab is installed editable from its repository, see README).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path

from analysis.config._base import REPO_ROOT, config_dir
from analysis.config.machine import (
    DIALECT_NAMES,
    REALTIME_OVERRIDE_DIALECTS,
    AxisTravel,
    FiveAxis,
    MachineConfig,
    RotaryAxis,
    SerialConfig,
)
from analysis.config.rig import (
    DaqConfig,
    Dynamometer,
    DynoChannel,
    FormerModeNames,
    Mode,
    RigConfig,
)
from analysis.config.tools import (
    MODE_FIELD_RENAMES,
    EndMill,
    EndMillCoefficients,
    FaceMill,
    FaceMillCoefficients,
    Holder,
    Material,
    MaterialLibrary,
    Provenance,
    Tool,
    ToolLibrary,
    ToolMode,
    renamed_mode_fields,
)
from analysis.errors import ConfigError
from analysis.validation import load_model


def _resolve(name_or_path: str | Path, sub: str) -> Path:
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists():
        return p
    cand = config_dir() / sub / f"{name_or_path}.toml"
    if cand.exists():
        return cand
    known = sorted(q.stem for q in (config_dir() / sub).glob("*.toml"))
    raise ConfigError(f"{sub[:-1]} '{name_or_path}' not found: not a file, and not one of {known}")


def load_machine(name_or_path: str | Path = "ace-h63") -> MachineConfig:
    """A machine by file path or by name in ``configs/machines/``."""
    return load_model(MachineConfig, _resolve(name_or_path, "machines"))


# User catalogues (issue 17): files next to the user's data, consulted before the shipped
# configs/tools.toml and configs/materials.toml, so that nobody edits the install. A module-level
# list, not a context variable: campaign runners read tools from worker threads.
_USER_CATALOGS: dict[str, list[str]] = {"tools": [], "materials": []}


@contextmanager
def user_catalogs(
    tools: str | Path | None = None, materials: str | Path | None = None
) -> Iterator[None]:
    """Within the block, :func:`get_tool` / :func:`load_tools` (and the material ones) look in
    ``tools`` / ``materials`` first: a name there shadows the shipped one. Each file is read now,
    so a bad one is one error naming it, before any work."""
    added = []
    for kind, path in (("tools", tools), ("materials", materials)):
        if path is None:
            continue
        if "\0" in str(path):  # open() would raise ValueError, not a config error
            raise ConfigError(f"{str(path)!r}: not a file name (it holds a NUL character)")
        (_tool_library if kind == "tools" else _material_library)(str(path))
        _USER_CATALOGS[kind].insert(0, str(path))
        added.append(kind)
    try:
        yield
    finally:
        for kind in added:
            _USER_CATALOGS[kind].pop(0)


def _catalog_files(kind: str, path: str | Path | None) -> list[str]:
    """The files searched, first match wins: ``path`` alone, else the user ones then shipped."""
    if path is not None:
        return [str(path)]
    return [*_USER_CATALOGS[kind], str(config_dir() / f"{kind}.toml")]


def catalog_source(kind: str, name: str) -> str:
    """The file a :func:`get_tool` (``kind`` "tools") or :func:`get_material` ("materials") of
    ``name`` reads it from now: the first of the user catalogues and the shipped file that holds
    it ("" if none does), so that a message about the tool names the user's file."""
    read = _tool_library if kind == "tools" else _material_library
    for f in _catalog_files(kind, None):
        if name in getattr(read(f), kind):
            return f
    return ""


def _not_found(kind: str, name: str, path: str | Path | None, known: list[str]) -> ConfigError:
    first, *rest = _catalog_files(f"{kind}s", path)
    nor = f" (nor in {', '.join(rest)})" if rest else ""
    return ConfigError(
        f"{first}: {kind} '{name}' not found{nor}; known {kind}s: {', '.join(sorted(known))}"
    )


@lru_cache(maxsize=8)
def _tool_library(path: str) -> ToolLibrary:
    return load_model(ToolLibrary, path)


def load_tools(path: str | Path | None = None) -> dict[str, EndMill | FaceMill]:
    """All tools of a tool library file (default: the user catalogues, then
    ``configs/tools.toml``; a user name shadows the shipped one)."""
    out: dict[str, EndMill | FaceMill] = {}
    for f in reversed(_catalog_files("tools", path)):
        out.update(_tool_library(f).tools)
    return out


def get_tool(name: str, path: str | Path | None = None) -> EndMill | FaceMill:
    tools = load_tools(path)
    if name not in tools:
        raise _not_found("tool", name, path, list(tools))
    return tools[name]


@lru_cache(maxsize=8)
def _material_library(path: str) -> MaterialLibrary:
    return load_model(MaterialLibrary, path)


def load_materials(path: str | Path | None = None) -> dict[str, Material]:
    """All materials (default: the user catalogues, then ``configs/materials.toml``)."""
    out: dict[str, Material] = {}
    for f in reversed(_catalog_files("materials", path)):
        out.update(_material_library(f).materials)
    return out


def get_material(name: str, path: str | Path | None = None) -> Material:
    mats = load_materials(path)
    if name not in mats:
        raise _not_found("material", name, path, list(mats))
    return mats[name]


def load_rig(path: str | Path | None = None) -> RigConfig:
    """Dynamometer and DAQ settings (default ``configs/rig.toml``)."""
    return load_model(RigConfig, path or config_dir() / "rig.toml")


#: the one face of the configs: ``from analysis.config import X`` whichever module holds X
__all__ = [
    "AxisTravel",
    "DIALECT_NAMES",
    "DaqConfig",
    "Dynamometer",
    "DynoChannel",
    "EndMill",
    "EndMillCoefficients",
    "FaceMill",
    "FaceMillCoefficients",
    "FiveAxis",
    "FormerModeNames",
    "Holder",
    "MODE_FIELD_RENAMES",
    "MachineConfig",
    "Material",
    "MaterialLibrary",
    "Mode",
    "Provenance",
    "REALTIME_OVERRIDE_DIALECTS",
    "REPO_ROOT",
    "RigConfig",
    "RotaryAxis",
    "SerialConfig",
    "Tool",
    "ToolLibrary",
    "ToolMode",
    "catalog_source",
    "config_dir",
    "get_material",
    "get_tool",
    "load_machine",
    "load_materials",
    "load_rig",
    "load_tools",
    "renamed_mode_fields",
    "user_catalogs",
]

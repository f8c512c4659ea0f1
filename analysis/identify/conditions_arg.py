"""What the commands take as cutting conditions and as the runs to fit, checked at the edge:
``--conditions`` as KEY=VALUE pairs, one JSON object, or a conditions table; run files or a run
catalogue, never both."""

from __future__ import annotations

import json
import math
from pathlib import Path

from analysis.errors import ConfigError

__all__ = ["conditions_arg", "parse_conditions", "runs_or_catalog"]


_NOT_FINITE = "not a finite number (a condition is a number or a name)"


def parse_conditions(items: list[str]) -> dict[str, object]:
    """``--conditions``: one JSON object, or KEY=VALUE pairs as `cutlab analyze forces` takes
    them (numbers become numbers: ``spindle_rpm=600 tool=phi10-flat``)."""
    if not items:
        return {}
    if len(items) == 1 and items[0].lstrip().startswith("{"):
        try:
            obj = json.loads(items[0])
        except json.JSONDecodeError as exc:
            raise ConfigError(f"--conditions {items[0]!r}: not a JSON object ({exc})") from None
        if not isinstance(obj, dict):
            raise ConfigError(f"--conditions {items[0]!r}: expected a JSON object")
        for key, val in obj.items():
            if isinstance(val, float) and not math.isfinite(val):
                raise ConfigError(f"--conditions: {key} = {val}: {_NOT_FINITE}")
        return obj
    out: dict[str, object] = {}
    for item in items:
        key, sep, val = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ConfigError(
                f"--conditions {item!r}: expected KEY=VALUE (e.g. spindle_rpm=600) or one JSON "
                "object"
            )
        if key in out:
            raise ConfigError(f"--conditions: {key} given twice")
        value = out[key] = _number_or_text(val.strip())
        if isinstance(value, float) and not math.isfinite(value):  # never stored as text
            raise ConfigError(f"--conditions {item!r}: {key} = {value}: {_NOT_FINITE}")
    return out


def _number_or_text(text: str) -> int | float | str:
    """600 -> 600, 0.236 -> 0.236, phi10-flat -> 'phi10-flat' (nan/inf become float nan/inf:
    the caller refuses them)."""
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            continue
    return text


def conditions_arg(items: list[str] | None) -> tuple[dict[str, object], str | None]:
    """``--conditions``: KEY=VALUE pairs (or one JSON object), or one conditions table (.csv,
    .toml, or any existing file): (pairs, table path)."""
    if (
        items
        and len(items) == 1
        and "=" not in items[0]
        and (
            Path(items[0]).suffix.lower() in (".csv", ".toml", ".tsv", ".txt")
            or Path(items[0]).is_file()
        )
    ):
        return {}, items[0]
    return parse_conditions(items or []), None


def runs_or_catalog(runs: list[str], catalog: str | None, **catalog_only: str | None) -> bool:
    """Whether the runs of `analyze forces` come from a catalogue (``catalog``) rather than
    files; refuses a mix, and a catalogue option (``catalog_only``: where, scheduler) without
    one."""
    if catalog is None:
        for opt, val in catalog_only.items():
            if val is not None:
                raise ConfigError(f"analyze forces: --{opt} needs --catalog DIR")
        if not runs:
            raise ConfigError("analyze forces: give run files, or --catalog DIR [--where EXPR]")
        return False
    if runs:
        raise ConfigError(f"analyze forces: run files ({runs[0]} ...) and --catalog "
                          f"{catalog}: give one or the other")  # fmt: skip
    return True

"""A TOML file into a validated config model, with errors a person can act on.

Every config model derives from :class:`Model` (frozen, unknown keys rejected). A problem is one
line per field: ``file:line: field = value: why (unit)``, e.g.::

    configs/tools.toml:14: tools.phi10-flat.diameter_mm = -10: must be > 0 (mm)

The unit is the field's description, followed through nested models (and through a union's member
named by the data's ``kind``); the line is found in the file's text by the field's table and key.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar, get_args

from pydantic import BaseModel, ConfigDict, ValidationError

from analysis.errors import ConfigError


class Model(BaseModel):
    """Base of all config models: frozen, unknown keys rejected."""

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)


M = TypeVar("M", bound=BaseModel)


def find_line(text: str, loc: tuple[Any, ...]) -> int | None:
    """Best-effort line of the key named by a pydantic error location (1-based)."""
    keys = [str(k) for k in loc if isinstance(k, str)]
    if not keys:
        return None
    lines = text.splitlines()
    # Prefer the key after the deepest table header that matches the location.
    start = 0
    for depth in range(len(keys) - 1, 0, -1):
        header = ".".join(keys[:depth])
        pat = re.compile(r"^\s*\[\[?\s*" + re.escape(header).replace(r"\.", r"\s*\.\s*") + r"\s*\]")
        for i, line in enumerate(lines):
            if pat.match(line):
                start = i
                break
        else:
            continue
        break
    key_pat = re.compile(r"^\s*\"?" + re.escape(keys[-1]) + r"\"?\s*=")
    for i in range(start, len(lines)):
        if key_pat.match(lines[i]):
            return i + 1
    for i, line in enumerate(lines):
        if key_pat.match(line) or re.match(r"^\s*\[\[?" + re.escape(".".join(keys)) + r"\]", line):
            return i + 1
    return None


def _all_models(root: type[BaseModel] = BaseModel) -> list[type[BaseModel]]:
    out, todo = [], [Model]
    while todo:
        m = todo.pop()
        out.append(m)
        todo.extend(m.__subclasses__())
    return out


def _models_in(annotation: Any) -> list[type[BaseModel]]:
    """The config models inside a field's type (``Foo``, ``Foo | None``, ``tuple[Foo, ...]``,
    ``dict[str, Foo]``, unions of models)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    out: list[type[BaseModel]] = []
    for arg in get_args(annotation):
        out += _models_in(arg)
    return out


def _field_unit(model: type[BaseModel], loc: tuple[Any, ...], data: Any = None) -> str:
    """The description (unit) of the field at ``loc``: followed from ``model`` through nested
    models (a union member chosen by the data's ``kind``); failing that, the first config model
    with a field of that name."""
    names = [p for p in loc if isinstance(p, str)]
    if not names:
        return ""
    owners: list[type[BaseModel]] = [model]
    cur = data
    for part in loc[:-1]:
        cur = cur.get(part) if isinstance(cur, Mapping) else (
            cur[part] if isinstance(cur, list | tuple) and isinstance(part, int)
            and part < len(cur) else None
        )  # fmt: skip
        if not isinstance(part, str):
            continue
        nxt = [m for o in owners if part in o.model_fields
               for m in _models_in(o.model_fields[part].annotation)]  # fmt: skip
        if not nxt:  # a dict key (tool or material name) or an unknown path: stay
            nxt = owners
        kind = cur.get("kind") if isinstance(cur, Mapping) else None
        tagged = [m for m in nxt if kind is not None and kind in _kinds(m)]
        owners = tagged or nxt
    for m in (*owners, *_all_models()):
        f = m.model_fields.get(names[-1])
        if f is not None and f.description:
            return f.description
    return ""


def _kinds(model: type[BaseModel]) -> tuple[Any, ...]:
    """The values a model's ``kind`` field allows (its Literal), () without one."""
    f = model.model_fields.get("kind")
    return get_args(f.annotation) if f is not None else ()


def _clean_loc(loc: tuple[Any, ...], data: Any) -> tuple[Any, ...]:
    """Drop the discriminator tags pydantic inserts into union locations, guided by the data."""
    out: list[Any] = []
    cur = data
    for part in loc:
        if isinstance(cur, Mapping) and part not in cur and cur.get("kind") == part:
            continue
        out.append(part)
        if isinstance(cur, Mapping):
            cur = cur.get(part)
        elif isinstance(cur, list | tuple) and isinstance(part, int) and part < len(cur):
            cur = cur[part]
        else:
            cur = None
    return tuple(out)


def format_validation_error(
    err: ValidationError, model: type[BaseModel], where: str, text: str = "", data: Any = None
) -> str:
    """One line per problem: ``file:line: field = value: why (unit)``."""
    out = []
    for e in err.errors():
        loc = _clean_loc(tuple(e["loc"]), data)
        field = ".".join(str(p) for p in loc) or "(top level)"
        line = find_line(text, loc) if text else None
        place = f"{where}:{line}" if line else where
        msg = e["msg"].removeprefix("Value error, ")
        if e["type"] == "extra_forbidden":
            msg = "unknown key (check the spelling; unknown keys are not ignored)"
        elif e["type"] == "missing":
            msg = "missing required field"
        unit = _field_unit(model, loc, data) if e["type"] not in ("extra_forbidden",) else ""
        inp = e.get("input")
        value = "" if e["type"] == "missing" or isinstance(inp, Mapping) else f" = {inp!r}"
        suffix = f" ({unit})" if unit and unit not in msg else ""
        out.append(f"{place}: {field}{value}: {msg}{suffix}")
    return "\n".join(out)


def read_toml(path: str | Path) -> tuple[dict[str, Any], str]:
    """Parse a TOML file; a syntax error names the file and line."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{p}: config file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{p}: cannot read config file: {exc}") from None
    try:
        return tomllib.loads(text), text
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: not valid TOML: {exc}") from None


def validate(model: type[M], data: Mapping[str, Any], where: str = "<config>", text: str = "") -> M:
    """Validate a mapping into ``model``; raise :class:`ConfigError` naming every bad field."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(format_validation_error(exc, model, where, text, data)) from None


def load_model(model: type[M], path: str | Path) -> M:
    data, text = read_toml(path)
    return validate(model, data, str(path), text)

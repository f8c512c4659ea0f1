"""A TOML file into a validated config model, with errors a person can act on.

Every config model derives from :class:`Model` (frozen, unknown keys rejected). A problem is one
line per field: ``file:line: field = value: why (unit)``, e.g.::

    configs/tools.toml:14: tools.phi10-flat.diameter_mm = -10: must be > 0 (mm)

The unit is the field's description, followed through nested models (and through a union's member
named by the data's ``kind``); the line is found in the file's text by the field's table and key.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal, TypeAlias, TypeVar, get_args, get_origin

import numpy as np
from pydantic import BaseModel, ConfigDict, ValidationError, model_validator
from pydantic_core import PydanticCustomError

from analysis.errors import ConfigError

#: the largest magnitude any number in a config may have: beyond it a value is a unit slip or a
#: typo (1e9 mm is 1000 km), and planning on it would only allocate or loop without end
MAGNITUDE_LIMIT = 1e9

#: a JSON document as the results' ``to_json`` give it (what ``json.dumps`` writes)
JsonValue: TypeAlias = str | int | float | bool | None | list["JsonValue"] | dict[str, "JsonValue"]
JsonObject: TypeAlias = dict[str, JsonValue]


def _mentions(annotation: Any, kinds: tuple[type, ...]) -> bool:
    """Whether a field's type names one of ``kinds`` anywhere (``float | None``,
    ``tuple[float, ...]``, ``Literal[1, -1]`` counts as int)."""
    if get_origin(annotation) is Literal:
        return any(type(v) in kinds for v in get_args(annotation))
    if isinstance(annotation, type):
        return annotation in kinds
    return any(_mentions(a, kinds) for a in get_args(annotation))


def check_number(value: object, what: str = "value") -> None:
    """Refuse what is not a plain number of sane size: booleans, text and magnitudes beyond
    :data:`MAGNITUDE_LIMIT` (NaN and inf are pydantic's ``allow_inf_nan``)."""
    if isinstance(value, bool | np.bool_):
        raise ValueError(f"{what}a boolean is not a number (write the number)")
    if isinstance(value, str):
        raise ValueError(f"{what}text is not a number (write it without quotes)")
    if isinstance(value, int | float) and math.isfinite(value) and abs(value) > MAGNITUDE_LIMIT:
        raise ValueError(f"{what}beyond +-{MAGNITUDE_LIMIT:g} (a unit slip?)")


def _check_numbers(value: Any, what: str = "") -> None:
    if isinstance(value, list | tuple):
        for i, v in enumerate(value):
            _check_numbers(v, f"item {i} = {v.item() if isinstance(v, np.generic) else v!r}: ")
    elif not isinstance(value, Mapping):  # a nested table is its own model's business
        check_number(value, what)


class Model(BaseModel):
    """Base of all config models: frozen, unknown keys rejected; numbers are numbers: finite
    (a field may allow inf with ``Field(allow_inf_nan=True)``), not booleans or text, and within
    +-:data:`MAGNITUDE_LIMIT`."""

    model_config = ConfigDict(
        extra="forbid", frozen=True, validate_default=True, allow_inf_nan=False
    )

    @model_validator(mode="before")
    @classmethod
    def _numbers_are_numbers(cls, data: Any) -> Any:
        if not isinstance(data, Mapping):
            return data
        for name, value in data.items():
            field = cls.model_fields.get(name) if isinstance(name, str) else None
            if field is None or value is None:
                continue
            ann = field.annotation
            if _mentions(ann, (int, float)) and not _mentions(ann, (bool, str)):
                try:
                    _check_numbers(value)
                except ValueError as exc:
                    # the field goes in the context: format_validation_error puts it in the loc
                    raise PydanticCustomError(
                        "not_a_number", str(exc), {"field": name, "value": value}
                    ) from None
        return data


M = TypeVar("M", bound=BaseModel)


def find_line(text: str, loc: tuple[str | int, ...]) -> int | None:
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
    out: list[type[BaseModel]] = []
    todo: list[type[BaseModel]] = [Model]
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
        if isinstance(part, str) and cur is not None and not isinstance(cur, Mapping):
            continue  # a union member's tag ("float", "list[float]") after a scalar or list
        out.append(part)
        if isinstance(cur, Mapping):
            cur = cur.get(part)
        elif isinstance(cur, list | tuple) and isinstance(part, int) and part < len(cur):
            cur = cur[part]
        else:
            cur = None
    return tuple(out)


def format_validation_error(
    err: ValidationError, model: type[BaseModel], where: str, text: str = "", data: object = None
) -> str:
    """One line per problem: ``file:line: field = value: why (unit)``."""
    out, seen = [], set()
    for e in err.errors():
        ctx = e.get("ctx") or {}
        if e["type"] == "not_a_number":  # raised by Model for the whole table: add the field
            e = {**e, "loc": (*e["loc"], ctx["field"]), "input": ctx["value"]}
        loc = _clean_loc(tuple(e["loc"]), data)
        if loc in seen:  # each member of a union (float | list[float]) refused it: say it once
            continue
        seen.add(loc)
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
        inp = inp.item() if isinstance(inp, np.generic) else inp  # nan, not np.float64(nan)
        value = "" if e["type"] == "missing" or isinstance(inp, Mapping) else f" = {inp!r}"
        suffix = f" ({unit})" if unit and unit not in msg else ""
        out.append(f"{place}: {field}{value}: {msg}{suffix}")
    return "\n".join(out)


def read_toml(path: str | Path) -> tuple[dict[str, object], str]:
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


def validate(model: type[M], data: object, where: str = "<config>", text: str = "") -> M:
    """Validate a mapping (or whatever a TOML key held) into ``model``; raise
    :class:`ConfigError` naming every bad field."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(format_validation_error(exc, model, where, text, data)) from None


def load_model(model: type[M], path: str | Path) -> M:
    data, text = read_toml(path)
    return validate(model, data, str(path), text)


# ---------------------------------------------------------------------------- reference


def _type_name(annotation: Any) -> str:
    """A short readable type: ``number``, ``list of number``, ``"a" | "b"``, ``table``."""
    origin, args = get_origin(annotation), get_args(annotation)
    if origin is Literal:
        return " \\| ".join(repr(a).replace("'", '"') for a in args)
    if isinstance(annotation, type):
        if issubclass(annotation, BaseModel):
            return "table"
        return {bool: "true/false", int: "integer", float: "number", str: "text"}.get(
            annotation, annotation.__name__
        )
    if origin in (list, tuple):
        inner = [a for a in args if a is not Ellipsis]
        kinds = sorted({_type_name(a) for a in inner})
        n = "" if Ellipsis in args or origin is list else f"{len(inner)} "
        return f"list of {n}{' or '.join(kinds)}"
    if origin is dict:
        return f"table of {_type_name(args[1])}"
    names = [_type_name(a) for a in args if a is not type(None)]
    return " or ".join(dict.fromkeys(names)) or str(annotation)


def _range(field: Any) -> str:
    parts = []
    for m in field.metadata:
        for attr, op in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<="),
                         ("min_length", "length >="), ("max_length", "length <=")):  # fmt: skip
            v = getattr(m, attr, None)
            if v is not None:
                parts.append(f"{op} {v:g}" if isinstance(v, float) else f"{op} {v}")
    return ", ".join(parts)


def _default(field: Any) -> str:
    if field.is_required():
        return "required"
    d = field.get_default(call_default_factory=True)
    if isinstance(d, BaseModel):
        return "(table)"
    if d is None:
        return "(none)"
    text = str(d).lower() if isinstance(d, bool) else repr(d).replace("'", '"')
    return f"`{text}`"


def model_reference(model: type[BaseModel], prefix: str = "") -> list[str]:
    """Markdown table rows (key, type, unit/meaning, default, range) of every key of ``model``
    and of its nested tables, keys dotted from ``prefix``; numbers without a range still obey
    +-:data:`MAGNITUDE_LIMIT`."""
    rows: list[str] = []
    for name, f in model.model_fields.items():
        key = f"{prefix}{name}"
        subs = _models_in(f.annotation)
        ann = f.annotation
        if get_origin(ann) is dict and subs:
            key += ".<name>"
        elif (
            subs
            and get_origin(ann) in (tuple, list)
            or (subs and any(get_origin(a) in (tuple, list) for a in get_args(ann)))
        ):
            key += "[]"
        desc = (f.description or "").replace("|", "\\|")
        rows.append(f"| `{key}` | {_type_name(ann)} | {desc} | {_default(f)} | {_range(f)} |")
        for sub in subs:
            tag = _kinds(sub)
            sub_prefix = f"{key}." if len(subs) == 1 or not tag else (
                f"{key}.({'/'.join(map(str, tag))})."
            )  # fmt: skip
            rows += model_reference(sub, sub_prefix)
    return rows


def reference_markdown(files: list[tuple[str, str, type[BaseModel]]]) -> str:
    """The configuration reference: for each (file pattern, what it is, model) a table of every
    key. Written to docs/configuration.md by ``python -m rig.cli.configref``."""
    out = [
        "# Configuration reference",
        "",
        "Generated from the config models by `python -m rig.cli.configref` (do not edit; "
        "tests/test_docs_current.py checks it is current).",
        "",
        "Every file is TOML. Unknown keys are errors. Numbers must be numbers: not true/false, "
        f"not text, not NaN or infinity, and within +-{MAGNITUDE_LIMIT:g} even where no range "
        "is given. `x[]` is an array of tables (`[[x]]`), `x.<name>` a table of named tables.",
        "",
    ]
    for pattern, what, model in files:
        out += [f"## `{pattern}`", "", what, "",
                "| key | type | unit / meaning | default | range |",
                "| --- | --- | --- | --- | --- |", *model_reference(model), ""]  # fmt: skip
    return "\n".join(out)

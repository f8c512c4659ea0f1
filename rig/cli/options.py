"""How commands are declared: a table of option rows per command (:func:`add_options`), a
command or a group in one call (:func:`command`, :func:`group`), options made from a model's
fields, their help next to the field (:func:`model_rows`), and the rows shared by several commands
(defined once, read the same everywhere: name, type, default, help, place in the help)."""

from __future__ import annotations

import argparse
import dataclasses
import inspect
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from types import UnionType
from typing import TYPE_CHECKING, Any, Literal, TypeVar, Union, cast, get_args, get_origin

from planning.nc import DIALECTS
from rig.cli.common import MAGNITUDE_LIMIT, count, image_file, number, positive

if TYPE_CHECKING:
    from pydantic import BaseModel

    from analysis.identify import ImportOptions

    M = TypeVar("M", bound=BaseModel)

#: a row's default that makes the option required
REQUIRED = ...
#: an option's row, ``(flags, type, default, help[, add_argument keywords])``; a table of rows
#: and groups of rows (nested)
Row = tuple[Any, ...]
Rows = Sequence[Any]


def add_options(p: argparse._ActionsContainer, rows: Rows) -> None:
    """Declare a command's options from a table, one row each: ``(flags, type, default, help)``
    and an optional dict of further ``add_argument`` keywords (metavar, nargs, dest); a sequence
    of rows in the table is a shared group (e.g. :func:`serial_rows`). ``flags`` is ``"file"``,
    ``"--x"`` or ``"-o --output"``; ``type`` is a parser (:mod:`rig.cli.common`), ``None``
    (text), ``bool`` (a flag) or a tuple of choices; default :data:`REQUIRED` makes the option
    required."""
    for row in rows:
        if not isinstance(row[0], str):  # a group of rows
            add_options(p, row)
            continue
        flags, kind, default, help, *extra = cast(Row, row)
        kw: dict[str, Any] = {"help": help, **(extra[0] if extra else {})}
        if kind is bool:
            kw["action"] = "store_true"
        elif isinstance(kind, tuple):
            kw["choices"] = kind
        elif kind is not None:
            kw["type"] = kind
        if default is REQUIRED:
            kw["required"] = flags.startswith("-") or None  # a positional is required anyway
            kw = {k: v for k, v in kw.items() if v is not None}
        elif kind is not bool and (default is not None or flags.startswith("-")):
            kw["default"] = default  # (a positional given a default is optional)
        p.add_argument(*flags.split(), **kw)


def group(sub: argparse._SubParsersAction, name: str, help: str) -> argparse._SubParsersAction:
    """A command group ``cutlab NAME NAME_COMMAND``: its subparsers (a subcommand is required)."""
    p = sub.add_parser(name, help=help)
    gsub = p.add_subparsers(dest=f"{name}_command", metavar=f"{name.upper()}_COMMAND")
    gsub.required = True
    return gsub


def command(
    sub: argparse._SubParsersAction, name: str, help: str, rows: Rows,
    func: Callable[[argparse.Namespace], int], *, catalogs: bool = False, **kw: Any,
) -> argparse.ArgumentParser:  # fmt: skip
    """A subcommand: its options from ``rows`` (:func:`add_options`), run by ``func``, with
    the user catalogues' --tools/--materials if ``catalogs``; ``kw`` to ``add_parser`` (a
    ``description`` may be a docstring: its indentation goes)."""
    if kw.get("description"):
        kw["description"] = inspect.cleandoc(kw["description"])
    p = sub.add_parser(name, help=help, **kw)
    add_options(p, [*rows, CATALOGS] if catalogs else rows)
    p.set_defaults(func=_with_catalogs(func) if catalogs else func)
    return p


#: ``--tools FILE`` / ``--materials FILE``: the user's catalogues, read before the shipped ones
#: (issue 17: next to the data, never edits inside the install)
CATALOGS = [
    ("--tools", Path, None, "your tool catalogue (TOML, [tools.NAME]), read before "
     "configs/tools.toml: a name in it shadows the shipped one",
     {"dest": "catalog_tools", "metavar": "FILE"}),
    ("--materials", Path, None, "your material catalogue (TOML, [materials.NAME]), read before "
     "configs/materials.toml: a name in it shadows the shipped one",
     {"dest": "catalog_materials", "metavar": "FILE"}),
]  # fmt: skip


def _with_catalogs(run: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
    """``run`` with the user's catalogues (:data:`CATALOGS`) in force."""

    def with_catalogs(a: argparse.Namespace) -> int:
        from analysis.config import user_catalogs

        with user_catalogs(a.catalog_tools, a.catalog_materials):
            return run(a)

    return with_catalogs


#: suffixes of a field's name (units, what a path is) that its option's name drops
#: (tool_diameter_mm: --tool-diameter, rig_path: --rig)
_UNIT_SUFFIXES = ("_mm_min", "_mm", "_rpm", "_n", "_s", "_hz", "_pct", "_png", "_path")


def model_rows(
    model: type, *, flags: Mapping[str, str] | None = None, skip: Sequence[str] = (),
    after: Mapping[str, Rows] | None = None,
) -> list[Row]:  # fmt: skip
    """:func:`add_options` rows, one per field of a dataclass (its ``metadata``: help, unit,
    gt/ge, le, metavar) or pydantic model (its ``Field``: description, gt/ge, le,
    ``json_schema_extra``: unit, flag, metavar, nargs, choices, kind ``path``/``picture``) but
    ``skip``: ``--name`` from the field's name without its unit suffix (or ``flags[field]``, or
    its ``flag``, a positional if without dashes), stored under the field's name; a number field
    is checked against the field's unit and range, a ``Literal`` field offers its choices, a list
    field takes several values, a bool field is a flag; a field without a default is required.
    The help lives once, next to the field it describes; ``after[field]``: rows that follow
    the field's in the help."""
    rows: list[Row] = []
    for name, (kind, default, meta) in _fields(model).items():
        if name in skip:
            continue
        flag = (flags or {}).get(name) or meta.get("flag") or "--" + _strip_unit(name).replace(
            "_", "-")  # fmt: skip
        kw: dict[str, Any] = {k: meta[k] for k in ("metavar", "nargs", "action") if k in meta}
        if flag.startswith("-"):
            kw["dest"] = name
        kind = _inner(kind)
        if kind in ("bool", bool):
            kind = bool
        elif get_origin(kind) is Literal or "choices" in meta:
            kind = meta.get("choices") or get_args(kind)
        else:
            if flag.startswith("-"):
                kw.setdefault("metavar", flag.split()[-1].lstrip("-").replace("-", "_").upper())
            parse = _KINDS.get(meta.get("kind", ""))
            kind = parse or (Path if kind is Path else _number(kind, meta))
        help = meta.get("help") or meta.get("unit")
        rows.append((flag, kind, default, help and help.replace("%", "%%"), kw))
        rows.extend((after or {}).get(name, ()))
    return rows


def from_args(model: type[M], args: argparse.Namespace, where: str) -> M:
    """The request ``model`` of a command's options (:func:`model_rows`), checked: a bad value
    is one line naming ``where`` (the command) and the field."""
    from analysis.validation import validate

    return validate(model, {k: getattr(args, k) for k in model.model_fields}, where)


#: parsers named by a field's ``kind`` (json_schema_extra)
_KINDS: dict[str, Callable[[str], Any]] = {"path": Path, "picture": image_file}


def _inner(kind: Any) -> Any:
    """A field's type without ``None`` and the list around it (``list[float] | None``: float)."""
    args = [a for a in get_args(kind) if a is not type(None)]
    if get_origin(kind) in (Union, UnionType) and len(args) == 1:
        return _inner(args[0])
    return _inner(args[0]) if get_origin(kind) is list and args else kind


def _number(kind: object, meta: Mapping[str, Any]) -> Callable[[str], float] | None:
    """A number field's parser (its unit and range), None for text."""
    if kind not in ("float", "int", float, int):
        return None
    lo = meta.get("gt", meta.get("ge"))
    return number(meta.get("unit", ""), lo, meta.get("le", MAGNITUDE_LIMIT), lo_open="gt" in meta,
                  integer=kind in ("int", int))  # fmt: skip


def _strip_unit(name: str) -> str:
    return next((name.removesuffix(u) for u in _UNIT_SUFFIXES if name.endswith(u)), name)


def _fields(model: type) -> dict[str, tuple[object, object, dict[str, Any]]]:
    """name: (type, default or REQUIRED, {help, unit, gt, ge, le, ...}) of a dataclass or
    pydantic model's fields."""
    if dataclasses.is_dataclass(model):
        return {f.name: (f.type, REQUIRED if f.default is dataclasses.MISSING else f.default,
                         dict(f.metadata)) for f in dataclasses.fields(model)}  # fmt: skip
    out = {}
    for name, info in model.model_fields.items():  # type: ignore[attr-defined]
        meta = {"help": info.description, **(info.json_schema_extra or {})}
        for c in info.metadata:  # annotated_types bounds
            meta.update({k: getattr(c, k) for k in ("gt", "ge", "le") if hasattr(c, k)})
        default = REQUIRED if info.is_required() else info.get_default(call_default_factory=True)
        out[name] = (info.annotation, default, meta)
    return out


def json_row(help: str | None = "JSON on stdout") -> Row:
    """``--json``: the command's result as JSON on stdout."""
    return ("--json", bool, None, help)


def rate_row(what: str = "exports") -> Row:
    """``--rate HZ`` for a file that does not say its sample rate."""
    return ("--rate", positive("Hz", 10_000_000), None, f"Hz, for {what} without a rate")


def rig_row(help: str = "rig config (default configs/rig.toml)") -> Row:
    """``--rig TOML``: the rig config (DAQ, dynamometer)."""
    return ("--rig", None, None, help)


def dialect_row(help: str, choices: tuple[str, ...] = DIALECTS) -> Row:
    """``--dialect NAME``: the controller a program is read or written for (default None: the
    machine's)."""
    return ("--dialect", choices, None, help)


def db_row(help: str | None = None) -> Row:
    """``--db FILE``: the rule base (default from configs/lab.toml)."""
    return ("--db", Path, None, help)


def serial_rows(
    machine_help: str, *, port: bool = True, protocol: bool = False,
    baud_help: str | None = "override serial.baudrate", timeout: bool = True,
) -> list[Row]:  # fmt: skip
    """The serial link to a controller, in this order: ``--port``, ``--protocol`` (required),
    ``--machine``, ``--baud``, ``--timeout`` (each but ``--machine`` optional here)."""
    port_help = "port name or pyserial URL (default: the machine config's)"
    rows: list[Row] = [("--port", None, None, port_help)] if port else []
    if protocol:
        rows.append(("--protocol", None, REQUIRED, "fanuc or grbl"))
    rows.append(("--machine", None, None, machine_help))
    if baud_help is not None:
        rows.append(("--baud", count(1, 4_000_000, "baud"), None, baud_help))
    if timeout:
        rows.append(("--timeout", positive("s", 3600), None, "override serial.timeout_s, s"))
    return rows


def import_rows() -> list[Row]:
    """How exports are read (`analyze forces`, `data import`): the options of
    :class:`analysis.identify.ImportOptions` (its conditions table: ``--conditions``)."""
    from analysis.identify import ImportOptions

    return model_rows(ImportOptions, skip=("table",))


def import_options(args: argparse.Namespace, table: Any = None) -> ImportOptions:
    """:func:`import_rows`' options as :class:`analysis.identify.ImportOptions` (with the
    conditions ``table`` if any)."""
    from analysis.identify import ImportOptions

    names = [f.name for f in dataclasses.fields(ImportOptions) if f.name != "table"]
    return ImportOptions(table=table, **{k: getattr(args, k) for k in names})

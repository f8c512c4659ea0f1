"""How commands are declared: a table of option rows per command (:func:`add_options`), a
command or a group in one call (:func:`command`, :func:`group`), options made from a model's
fields, their help next to the field (:func:`model_rows`), and the rows shared by several commands
(defined once, read the same everywhere: name, type, default, help, place in the help)."""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from planning.nc import DIALECTS
from rig.cli.common import MAGNITUDE_LIMIT, count, number, positive

if TYPE_CHECKING:
    from analysis.identify import ImportOptions

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
            kw["required"] = True
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
    the user catalogues' --tools/--materials if ``catalogs``; ``kw`` to ``add_parser``."""
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


#: unit suffixes of a field's name that its option's name drops (tool_diameter_mm: --tool-diameter)
_UNIT_SUFFIXES = ("_mm_min", "_mm", "_rpm", "_n", "_s", "_hz", "_pct")


def model_rows(
    model: type, *, flags: Mapping[str, str] | None = None, skip: Sequence[str] = ()
) -> list[Row]:
    """:func:`add_options` rows, one per field of a dataclass (its ``metadata``: help, unit,
    gt/ge, le, metavar) or pydantic model (its ``Field``: description, gt/ge, le,
    ``json_schema_extra`` unit) but ``skip``: ``--name`` from the field's name without its unit
    suffix (or ``flags[field]``), stored under the field's name; a number field is checked
    against the field's unit and range, a bool field is a flag; a field without a default is
    required. The help lives once, next to the field it describes."""
    rows = []
    for name, (kind, default, meta) in _fields(model).items():
        if name in skip:
            continue
        flag = (flags or {}).get(name) or "--" + _strip_unit(name).replace("_", "-")
        kw = {"dest": name}
        if kind in ("bool", bool):
            kind = bool
        else:
            kw["metavar"] = meta.get("metavar") or flag.lstrip("-").replace("-", "_").upper()
            kind = _number(kind, meta)
        rows.append((flag, kind, default, meta.get("help") or meta.get("unit"), kw))
    return rows


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
    """name: (type, default or REQUIRED, {help, unit, gt, ge, le}) of a dataclass or pydantic
    model's fields."""
    if dataclasses.is_dataclass(model):
        return {f.name: (f.type, REQUIRED if f.default is dataclasses.MISSING else f.default,
                         dict(f.metadata)) for f in dataclasses.fields(model)}  # fmt: skip
    out = {}
    for name, info in model.model_fields.items():  # type: ignore[attr-defined]
        meta = {"help": info.description, **(info.json_schema_extra or {})}
        for c in info.metadata:  # annotated_types bounds
            meta.update({k: getattr(c, k) for k in ("gt", "ge", "le") if hasattr(c, k)})
        out[name] = (info.annotation, REQUIRED if info.is_required() else info.default, meta)
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


#: ``--stock`` and ``--spacing``: the stock a program is cut from on the Z-map (plan check, feed
#: and simulate)
STOCK = [
    ("--stock", None, None, "box:XMIN,XMAX,YMIN,YMAX,BOTTOM,TOP | mesh (.stl) | stock TOML "
     "(default: derived from the program's feed moves, printed)"),
    ("--spacing", positive("mm", 100), None, "Z-map grid spacing, mm (default 0.25)"),
]  # fmt: skip
#: ``--lobes`` (plan check, feed and rough)
LOBES = ("--lobes", Path, None, "stability lobes CSV (spindle_rpm,depth_limit_mm; "
         "`cutlab analyze stability -o`), default: the tool's modes if any")  # fmt: skip
#: the flags of :class:`analysis.identify.ImportOptions`'s fields
IMPORT_FLAGS = {"pattern": "--conditions-pattern", "zero_file": "--zero", "tools_path": "--tools",
                "materials_path": "--materials"}  # fmt: skip


def import_rows() -> list[Row]:
    """How exports are read (`analyze forces`, `data import`): the options of
    :class:`analysis.identify.ImportOptions` (its conditions table: ``--conditions``)."""
    from analysis.identify import ImportOptions

    return model_rows(ImportOptions, flags=IMPORT_FLAGS, skip=("table",))


def import_options(args: argparse.Namespace) -> tuple[dict[str, Any], ImportOptions]:
    """``--conditions`` (pairs, or a table) and :func:`import_rows`' options as
    (pairs, :class:`analysis.identify.ImportOptions`)."""
    from analysis.identify import ImportOptions
    from analysis.identify.conditions_arg import conditions_arg

    pairs, table = conditions_arg(args.conditions)
    names = [f.name for f in dataclasses.fields(ImportOptions) if f.name != "table"]
    return pairs, ImportOptions(table=table, **{k: getattr(args, k) for k in names})

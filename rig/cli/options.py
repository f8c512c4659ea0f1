"""Options shared by several commands, one function per group: a shared option is defined once
and reads the same everywhere (name, type, default, help, place in the help)."""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from planning.nc import DIALECTS
from rig.cli.common import MAGNITUDE_LIMIT, count, number, positive

if TYPE_CHECKING:
    from analysis.identify import ImportOptions

#: a row's default that makes the option required
REQUIRED = ...


def add_options(p: argparse.ArgumentParser, rows: Sequence[tuple]) -> None:
    """Declare a command's options from a table, one row each: ``(flags, type, default, help)``
    and an optional dict of further ``add_argument`` keywords (metavar, nargs, dest). ``flags``
    is ``"file"``, ``"--x"`` or ``"-o --output"``; ``type`` is a parser (:mod:`rig.cli.common`),
    ``None`` (text), ``bool`` (a flag) or a tuple of choices; default :data:`REQUIRED` makes the
    option required."""
    for flags, kind, default, help, *extra in rows:
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


#: unit suffixes of a field's name that its option's name drops (tool_diameter_mm: --tool-diameter)
_UNIT_SUFFIXES = ("_mm_min", "_mm", "_rpm", "_n", "_s", "_hz", "_pct")


def model_options(
    p: argparse.ArgumentParser, model: type, *, flags: Mapping[str, str] | None = None
) -> None:
    """One option per field of a dataclass (its ``metadata``: help, unit, gt/ge, le) or pydantic
    model (its ``Field``: description, gt/ge, le, ``json_schema_extra`` unit): ``--name`` from the
    field's name without its unit suffix (or ``flags[field]``), stored under the field's name; a
    number field is checked against the field's unit and range; a field without a default is
    required. The help lives once, next to the field it describes."""
    for name, (kind, default, meta) in _fields(model).items():
        flag = (flags or {}).get(name) or "--" + _strip_unit(name).replace("_", "-")
        kw: dict[str, Any] = {"dest": name, "metavar": flag.lstrip("-").replace("-", "_").upper(),
                              "help": meta.get("help") or meta.get("unit")}  # fmt: skip
        if kind in ("float", "int", float, int):
            lo = meta.get("gt", meta.get("ge"))
            kw["type"] = number(meta.get("unit", ""), lo, meta.get("le", MAGNITUDE_LIMIT),
                                lo_open="gt" in meta, integer=kind in ("int", int))  # fmt: skip
        if default is REQUIRED:
            kw["required"] = True
        else:
            kw["default"] = default
        p.add_argument(flag, **kw)


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


PORT_HELP = "port name or pyserial URL (default: the machine config's)"
BAUD_HELP = "override serial.baudrate"


def json_option(p: argparse.ArgumentParser, help: str | None = "JSON on stdout") -> None:
    """``--json``: the command's result as JSON on stdout."""
    p.add_argument("--json", action="store_true", help=help)


def rate_option(p: argparse.ArgumentParser, what: str = "exports") -> None:
    """``--rate HZ`` for a file that does not say its sample rate."""
    p.add_argument("--rate", type=positive("Hz", 10_000_000), default=None,
                   help=f"Hz, for {what} without a rate")  # fmt: skip


def rig_option(
    p: argparse.ArgumentParser, help: str = "rig config (default configs/rig.toml)"
) -> None:
    """``--rig TOML``: the rig config (DAQ, dynamometer)."""
    p.add_argument("--rig", default=None, help=help)


def dialect_option(
    p: argparse.ArgumentParser, help: str, choices: tuple[str, ...] = DIALECTS
) -> None:
    """``--dialect NAME``: the controller a program is read or written for (default None: the
    machine's)."""
    p.add_argument("--dialect", choices=choices, default=None, help=help)


def serial_options(
    p: argparse.ArgumentParser, machine_help: str, *, port: bool = True,
    protocol: bool = False, baud_help: str | None = BAUD_HELP, timeout: bool = True,
) -> None:  # fmt: skip
    """The serial link to a controller, in this order: ``--port``, ``--protocol`` (required),
    ``--machine``, ``--baud``, ``--timeout`` (each but ``--machine`` optional here)."""
    if port:
        p.add_argument("--port", help=PORT_HELP)
    if protocol:
        p.add_argument("--protocol", required=True, help="fanuc or grbl")
    p.add_argument("--machine", help=machine_help)
    if baud_help is not None:
        p.add_argument("--baud", type=count(1, 4_000_000, "baud"), help=baud_help)
    if timeout:
        p.add_argument("--timeout", type=positive("s", 3600), help="override serial.timeout_s, s")


def rule_db_option(p: argparse.ArgumentParser, help: str | None = None) -> None:
    """``--db FILE``: the rule base (default from configs/lab.toml)."""
    p.add_argument("--db", type=Path, help=help)


def stock_options(p: argparse.ArgumentParser) -> None:
    """``--stock`` and ``--spacing``: the stock a program is cut from on the Z-map (plan check,
    feed and simulate)."""
    p.add_argument("--stock", help="box:XMIN,XMAX,YMIN,YMAX,BOTTOM,TOP | mesh (.stl) | stock TOML "
        "(default: derived from the program's feed moves, printed)")  # fmt: skip
    p.add_argument(
        "--spacing", type=positive("mm", 100), help="Z-map grid spacing, mm (default 0.25)"
    )


def limit_options(p: argparse.ArgumentParser) -> None:
    """``--lobes`` (plan check, feed and rough)."""
    p.add_argument("--lobes", type=Path, help="stability lobes CSV (spindle_rpm,depth_limit_mm; "
                   "`cutlab analyze stability -o`), default: the tool's modes if any")  # fmt: skip


def import_group(p: argparse.ArgumentParser) -> None:
    """How exports are read (`analyze forces`, `data import`): ``--axes``,
    ``--conditions-pattern``, ``--zero``, ``--zeroed``, ``--tools``, ``--materials``."""
    p.add_argument(
        "--axes", metavar="x=COL,y=COL,z=COL",
        help="file columns (or run-file channels) for cutlab's x (feed), y (cross-feed), z (tool "
        "axis), a '-' flips the sign: x=-Fy,y=Fx,z=-Fz; or 'auto': the signed permutation whose "
        "end-mill fit gives positive Ktc, Krc, Kac with the smallest residual (refused when the "
        "runs cannot tell; slots alone cannot tell x from y) (default: the rig config's "
        "dynamometer, else columns named Fx, Fy, Fz; a mapping giving a negative cutting "
        "coefficient or fitting clearly worse than another is refused)",
    )  # fmt: skip
    for name, metavar, text in (
        ("--conditions-pattern", "PATTERN",
         "conditions from file names: 'cut_{spindle_rpm}rpm_f{feed_mm_min}.txt'"),
        ("--zero", "FILE", "an export of the same channels at rest: its mean is the offset"),
        ("--zeroed", None, "the exports are already zeroed: subtract no offset"),
        ("--tools", "FILE", "your tool catalogue (TOML, [tools.NAME]), before configs/tools.toml"),
        ("--materials", "FILE", "your material catalogue (TOML), before configs/materials.toml"),
    ):  # fmt: skip
        kw = {"action": "store_true"} if metavar is None else {"metavar": metavar}
        p.add_argument(name, help=text, **kw)  # type: ignore[arg-type]


def import_options(args: argparse.Namespace) -> tuple[dict[str, Any], ImportOptions]:
    """``--conditions`` (pairs, or a table) and :func:`import_group`'s options as
    (pairs, :class:`analysis.identify.ImportOptions`)."""
    from analysis.identify import ImportOptions
    from analysis.identify.conditions_arg import conditions_arg

    pairs, table = conditions_arg(args.conditions)
    opts = ImportOptions(axes=args.axes, table=table, pattern=args.conditions_pattern,
                         zero_file=args.zero, zeroed=args.zeroed, tools_path=args.tools,
                         materials_path=args.materials)  # fmt: skip
    return pairs, opts

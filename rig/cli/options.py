"""Options shared by several commands, one function per group: a shared option is defined once
and reads the same everywhere (name, type, default, help, place in the help)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from planning.nc import DIALECTS
from rig.cli.common import count, positive

if TYPE_CHECKING:
    from analysis.identify import ImportOptions

#: the order the post-processing commands (plan rough/feed/orient) list the controllers in
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

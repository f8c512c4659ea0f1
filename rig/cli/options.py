"""Options shared by several commands, one function per group: a shared option is defined once
and reads the same everywhere (name, type, default, help, place in the help)."""

from __future__ import annotations

import argparse
from pathlib import Path

from planning.nc import DIALECTS
from rig.cli.common import count, positive

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

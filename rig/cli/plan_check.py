"""`cutlab plan check PROGRAM --tool T --material M [--machine M] [--stock S] [--lobes CSV]
[--json] [--plot PNG]`: every block of a program against what the machine and tool can take
(spindle power and torque, tool deflection and chip thickness, the stability limit); what it
does is :func:`planning.limits.check_job`."""

from __future__ import annotations

import argparse
from pathlib import Path

from rig.cli.common import add_catalog_options, positive, print_json, print_lines, status
from rig.cli.options import limit_options, stock_options
from rig.terminal import Progress


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``check`` to the ``plan`` group."""
    p = sub.add_parser(
        "check", help="check a program's blocks against machine and tool limits",
        description="Exit status: 0 every block within every limit (verdict 'within'); 3 a block "
        "breaks a limit ('violations'); 4 none breaks one but a limit could not be checked (no "
        "tool modes or lobes, no spindle curve, a drill, nothing cut: 'unchecked', listed); "
        "2 bad input.",
    )  # fmt: skip
    p.add_argument("program", type=Path, help="NC program")
    p.add_argument("--tool", help="end mill in configs/tools.toml, or T1=NAME,T2=NAME for a "
                   "program that changes tools (each section checked with its own)")  # fmt: skip
    p.add_argument("--material", help="material (configs/materials.toml): force coefficients")
    p.add_argument("--machine", default="ace-h63", help="machine config name or path")
    stock_options(p)
    limit_options(p)
    p.add_argument("--spindle", type=positive("rpm", 100_000),
                   help="rpm where the program has no S")  # fmt: skip
    p.add_argument("--plot", type=Path, help="PNG of each quantity per block against its limit")
    p.add_argument("--json", action="store_true", help="machine-readable output on stdout")
    p.set_defaults(func=run)
    add_catalog_options(p)


#: exit status of each verdict (0 within, 3 violations, 4 unchecked; 2 is bad input)
VERDICT_EXIT = {"within": 0, "violations": 3, "unchecked": 4}
#: exit status of the commands that write a program (plan feed, plan rough) by its verdict: 3 when
#: a block breaks a limit (the program is written, and must not pass for a good one in a script);
#: a limit not checked is printed and in the JSON, the program being what the command makes
WRITTEN_EXIT = {"within": 0, "violations": 3, "unchecked": 0}


def print_stock(stock: dict) -> None:
    from planning.limits.text import stock_note

    if (note := stock_note(stock)) is not None:
        status(note)


def run(a: argparse.Namespace) -> int:
    from planning.limits import check_job
    from planning.limits.text import check_lines

    with Progress("simulate", unit="piece") as bar:
        _, out = check_job(
            a.program, tool_name=a.tool, material=a.material, machine=a.machine,
            stock_spec=a.stock, spacing_mm=a.spacing, lobes=a.lobes, spindle_rpm=a.spindle,
            plot=a.plot, progress=bar,
        )  # fmt: skip
    code = VERDICT_EXIT[out["verdict"]]
    if a.json:
        print_json(out)
        return code
    print_stock(out["stock"])
    print_lines(check_lines(out))
    if out["png"]:
        status(f"wrote {out['png']}")
    return code

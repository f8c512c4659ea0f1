"""`cutlab plan check`: every block of a program against what the machine and tool can take
(:func:`planning.limits.check_job`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from rig.cli.common import positive, show
from rig.cli.options import LOBES, STOCK, command
from rig.terminal import Progress


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``check`` to the ``plan`` group."""
    command(sub, "check", "check a program's blocks against machine and tool limits", [
        ("program", Path, None, "NC program"),
        ("--tool", None, None, "end mill in configs/tools.toml, or T1=NAME,T2=NAME for a program "
         "that changes tools (each section checked with its own)"),
        ("--material", None, None, "material (configs/materials.toml): force coefficients"),
        ("--machine", None, "ace-h63", "machine config name or path"),
        STOCK, LOBES,
        ("--spindle", positive("rpm", 100_000), None, "rpm where the program has no S"),
        ("--plot", Path, None, "PNG of each quantity per block against its limit"),
        ("--json", bool, None, "machine-readable output on stdout"),
    ], run, catalogs=True, description="Exit status: 0 every block within every limit (verdict "
       "'within'); 3 a block breaks a limit ('violations'); 4 none breaks one but a limit could "
       "not be checked (no tool modes or lobes, no spindle curve, a drill, nothing cut: "
       "'unchecked', listed); 2 bad input.")  # fmt: skip


#: exit status of each verdict (0 within, 3 violations, 4 unchecked; 2 is bad input)
VERDICT_EXIT = {"within": 0, "violations": 3, "unchecked": 4}
#: exit status of the commands that write a program (plan feed, plan rough) by its verdict: 3 when
#: a block breaks a limit (the program is written, and must not pass for a good one in a script);
#: a limit not checked is printed and in the JSON, the program being what the command makes
WRITTEN_EXIT = {"within": 0, "violations": 3, "unchecked": 0}


def run(a: argparse.Namespace) -> int:
    from planning.limits import check_job
    from planning.limits.text import check_lines, stock_note

    with Progress("simulate", unit="piece") as bar:
        _, out = check_job(
            a.program, tool_name=a.tool, material=a.material, machine=a.machine,
            stock_spec=a.stock, spacing_mm=a.spacing, lobes=a.lobes, spindle_rpm=a.spindle,
            plot=a.plot, progress=bar,
        )  # fmt: skip
    return show(a.json, out, lambda: check_lines(out), VERDICT_EXIT[out["verdict"]],
                notes=lambda: [stock_note(out["stock"])],
                after=[f"wrote {out['png']}" if out["png"] else None])  # fmt: skip

"""`cutlab plan check PROGRAM --tool T --material M [--machine M] [--stock S] [--lobes CSV]
[--json] [--plot PNG]`: every block of a program against what the machine and tool can take
(spindle power and torque, tool deflection and chip thickness, the stability limit); what it
does is :func:`planning.limits.check_job`."""

from __future__ import annotations

import argparse
from pathlib import Path

from rig.cli._common import add_catalog_options, positive


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``check`` to the ``plan`` group."""
    p = sub.add_parser("check", help="check a program's blocks against machine and tool limits")
    p.add_argument("program", type=Path, help="NC program")
    p.add_argument("--tool", help="end mill in configs/tools.toml")
    p.add_argument("--material", help="material (configs/materials.toml): force coefficients")
    p.add_argument("--machine", default="ace-h63", help="machine config name or path")
    p.add_argument("--stock", help="box:XMIN,XMAX,YMIN,YMAX,BOTTOM,TOP | mesh (.stl) | stock TOML "
        "(default: a box over the feed moves, top at Z0)")  # fmt: skip
    p.add_argument(
        "--spacing", type=positive("mm", 100), help="Z-map grid spacing, mm (default 0.25)"
    )
    add_limit_options(p)
    p.add_argument("--spindle", type=positive("rpm", 100_000),
                   help="rpm where the program has no S")  # fmt: skip
    p.add_argument("--plot", type=Path, help="PNG of each quantity per block against its limit")
    p.add_argument("--json", action="store_true", help="machine-readable output on stdout")
    p.set_defaults(func=run)
    add_catalog_options(p)


def add_limit_options(p: argparse.ArgumentParser) -> None:
    """``--lobes`` (shared by plan check, feed and rough)."""
    p.add_argument("--lobes", type=Path, help="stability lobes CSV (spindle_rpm,depth_limit_mm; "
                   "`cutlab analyze stability -o`), default: the tool's modes if any")  # fmt: skip


def print_violations(violations: list[dict], limit: int = 20) -> None:
    from rig.cli._common import print_table

    if not violations:
        print("every block within every limit")
        return
    print(f"{len(violations)} violations (block, limit, value, allowed, margin %):")
    print_table(violations[:limit])
    if len(violations) > limit:
        print(f"... and {len(violations) - limit} more (--json lists all)")


def run(a: argparse.Namespace) -> int:
    from planning.limits import check_job
    from rig.cli._common import Progress, print_json, status

    with Progress("simulate", unit="piece") as bar:
        _, out = check_job(
            a.program, tool_name=a.tool, material=a.material, machine=a.machine,
            stock_spec=a.stock, spacing_mm=a.spacing, lobes=a.lobes, spindle_rpm=a.spindle,
            plot=a.plot, progress=bar,
        )  # fmt: skip
    if a.json:
        print_json(out)
        return 0
    for n in out["limits"]["notes"]:
        status("note: " + n)
    if not out["cutting_blocks"]:  # e.g. the default stock (top at Z0) under a part's program
        status(f"note: {a.program}: no block removes stock (give the stock with --stock)")
    print_violations(out["violations"])
    for k, w in out["worst"].items():
        print(f"worst {k}: {w['value']:.4g} of {w['allowed']:.4g} at block {w['block']} "
              f"(margin {w['margin_pct']} %)")  # fmt: skip
    if out["png"]:
        status(f"wrote {out['png']}")
    return 0

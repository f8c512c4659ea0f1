"""`cutlab plan feed` and `cutlab plan simulate` (seed 001): the load-based feed post-processor
and Z-map virtual machining; what they do is :mod:`planning.feed.job`."""

from __future__ import annotations

import argparse
from pathlib import Path

from rig.cli.common import image_file, positive, print_lines, show, status
from rig.cli.options import LOBES, REQUIRED, STOCK, Rows, command, db_row, dialect_row
from rig.terminal import Progress


# fmt: off
def register(sub: argparse._SubParsersAction) -> None:
    """Add ``feed`` and ``simulate`` to the ``plan`` group."""
    command(sub, "feed", "adjust feeds by predicted cutting load (seed 001)", FEED, _feed,
            catalogs=True, description="Exit status: 0 when the program is written and its "
            "verdict (printed, and 'verdict' in --json) is 'within' or 'unchecked' (without "
            "--material: the limits not checked are listed); 3 when it is written but a block "
            "breaks a limit ('violations'); 2 bad input, or a program that removes nothing from "
            "its stock.")
    command(sub, "simulate", "Z-map virtual machining of a program or a plan", [
        ("program", Path, None, "NC program, or an operation plan (.toml)"), COMMON,
        ("--png", image_file, None, "final stock PNG"),
    ], _simulate, catalogs=True)


#: what feed and simulate share: the machine, the tool, the stock
COMMON: Rows = [
    ("--machine", None, "ace-h63", "machine config name or path"),
    ("--tool", None, None, "end mill of the tool catalogue, or T1=NAME,T2=NAME for a program "
     "that changes tools (needed for a program; plans name theirs)"),
    STOCK,
    ("--no-holder-check", bool, None, "skip holder/stock checks"),
    ("--json", bool, None, "machine-readable output on stdout"),
]
FEED: Rows = (
    ("program", Path, None, "NC program (G21 or G20)"),
    ("--rules", None, None, "rule file (TOML) or rule-base name / id; T1=RULE,T2=RULE for a "
     "program that changes tools (a tool left out, e.g. a drill, keeps its feeds); default: each "
     "tool's rule from the rule base by tool and --material (a tool it lacks keeps its feeds)"),
    db_row("rule base for a name / id (default from lab.toml)"),
    COMMON,
    ("-o --output", Path, REQUIRED, "adjusted program to write"),
    dialect_row("controller to write for (default: the machine's)"),
    ("--report", Path, None, "report folder (default: OUT's folder)"),
    ("--min-piece", positive("mm", 1000), 5.0, "shortest split block, mm"),
    ("--no-split", bool, None, "one feed per block, no splits"),
    ("--force-limit", positive("N", 1e6), None, "largest predicted peak force, N"),
    ("--material", None, None, "material (configs/materials.toml): predicted peak force per "
     "block, and the coefficients for --force-limit"),
    ("--spindle", positive("rpm", 100_000), None, "rpm for the force model if the program has "
     "no S"),
    ("--limit", bool, None, "cap every feed by the machine's and tool's limits (planning.limits; "
     "needs --material)"),
    LOBES,
)
# fmt: on


def _feed(a: argparse.Namespace) -> int:
    from planning.feed import feed_program
    from planning.feed.text import feed_lines, feed_notes
    from planning.limits.feed_options import feed_limits
    from planning.limits.text import stock_note, verdict_lines, violation_lines
    from rig.cli.plan_check import WRITTEN_EXIT

    lim = feed_limits(a.rules, a.tool, a.material, a.machine, a.lobes, a.force_limit, a.limit,
                      a.spindle)  # fmt: skip
    with Progress("simulate", unit="piece") as bar:
        result, s = feed_program(
            a.program, a.rules, a.output, db=a.db, machine=a.machine, tool_name=a.tool,
            stock_spec=a.stock, spacing_mm=a.spacing, report_dir=a.report, progress=bar,
            warn=status, min_piece_mm=a.min_piece, split=not a.no_split,
            check_holder=not a.no_holder_check, force_limit_n=a.force_limit,
            material=None if lim.lookup_only else a.material, spindle_rpm=a.spindle,
            dialect=a.dialect, limit_step=lim.step, feed_cap=lim.cap, rules_material=a.material,
        )  # fmt: skip
    code = WRITTEN_EXIT[s["verdict"]]
    if a.json:
        s.setdefault("violations", [])  # the command contract: always a list
        return show(True, s, code=code)
    if (note := stock_note(s["stock"])) is not None:
        status(note)
    print_lines(violation_lines(s["violations"]))  # between the stock's note and the feeds' notes
    return show(False, s, lambda: [*feed_lines(s), *verdict_lines(s)], code,
                notes=lambda: feed_notes(s, result.simulation.contacts, a.program, a.output))


def _simulate(a: argparse.Namespace) -> int:
    from planning.feed import simulate_job
    from planning.feed.text import simulate_lines, simulate_notes
    from planning.limits.text import stock_note

    with Progress("simulate", unit="piece") as bar:
        results, out = simulate_job(
            a.program, machine=a.machine, tool_name=a.tool, stock_spec=a.stock,
            spacing_mm=a.spacing, check_holder=not a.no_holder_check, png=a.png, progress=bar,
        )  # fmt: skip
    contacts = [r.simulation.contacts for r in results]
    return show(a.json, out, lambda: simulate_lines(out),
                notes=lambda: [stock_note(out["stock"]), *simulate_notes(out, contacts)],
                after=[f"wrote {a.png}" if a.png else None])  # fmt: skip

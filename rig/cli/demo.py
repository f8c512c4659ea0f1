"""`cutlab demo` — cutlab's main job on the simulated rig: seed 003's face-milling campaign.

Runs ``configs/campaigns/facemill-ploughing.toml`` on the simulated rig (a simulated Fanuc control
on a pseudo-terminal fed by the real DNC streamer, the simulated machine cutting with the
material's true coefficients, the dynamometer's modes, the simulated DAQ and the HDF5 logger),
identifies the face-mill coefficients from the recorded runs, predicts the validation runs, and
writes the report folder. It prints the identified coefficients beside the simulator's truth.

    cutlab demo                    # -> ./out/demo/facemill-ploughing/report/report.md
    cutlab demo --json             # the same figures as JSON
    cutlab demo --forces independent   # forces from rig.sim.facemill_independent (written
                                       # apart from analysis.forces) -> ./out/demo-independent
"""

from __future__ import annotations

import argparse

from rig.cli.common import show, status
from rig.cli.options import command

CAMPAIGN = (
    "facemill-ploughing"  # rig.report.DEMO_CAMPAIGN (not imported: `cutlab --help` stays fast)
)


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    what = "run seed 003's face-milling campaign on the simulated rig and report it"
    command(sub, "demo", what, [
        ("--out", None, None, "output folder (default: out/demo, out/demo-independent with "
         "--forces independent)"),
        ("--campaign", None, CAMPAIGN, "campaign to run (default: %(default)s)"),
        ("--resume", bool, None, "keep finished runs of an earlier demo"),
        ("--forces", ("seed003", "independent"), None, "where the twin's face-milling forces come "
         "from: seed003 (analysis.forces, the model the fit inverts) or independent (a simulator "
         "written apart from it); default: the campaign's [sim] force_model"),
        ("--json", bool, None, "machine-readable summary on stdout"),
        ("--quiet", bool, None, "no progress display"),
    ], _demo, description=__doc__.split("\n\n")[1] if __doc__ else None)  # fmt: skip


def _demo(args: argparse.Namespace) -> int:
    from rig.report import run_demo
    from rig.report.demo_text import demo_lines

    out = args.out or ("out/demo-independent" if args.forces == "independent" else "out/demo")
    res = run_demo(args.campaign, out, resume=args.resume, progress=not args.quiet,
                   status=status, forces=args.forces)  # fmt: skip
    if res.stopped:
        status(f"demo: stopped; run `cutlab demo --resume` to continue ({res.folder})")
        return 130
    return show(args.json, res.summary(), lambda: demo_lines(res), 0 if res.ok else 1)

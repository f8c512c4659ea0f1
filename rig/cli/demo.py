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

from rig.cli.common import print_json, print_lines, status

CAMPAIGN = (
    "facemill-ploughing"  # rig.report.DEMO_CAMPAIGN (not imported: `cutlab --help` stays fast)
)


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    p = sub.add_parser(
        "demo",
        help="run seed 003's face-milling campaign on the simulated rig and report it",
        description=__doc__.split("\n\n")[1] if __doc__ else None,
    )
    p.add_argument("--out", default=None,
                   help="output folder (default: out/demo, out/demo-independent with --forces "
                   "independent)")  # fmt: skip
    p.add_argument("--campaign", default=CAMPAIGN, help="campaign to run (default: %(default)s)")
    p.add_argument("--resume", action="store_true", help="keep finished runs of an earlier demo")
    p.add_argument("--forces", choices=("seed003", "independent"), default=None,
                   help="where the twin's face-milling forces come from: seed003 "
                   "(analysis.forces, the model the fit inverts) or independent (a simulator "
                   "written apart from it); default: the campaign's [sim] force_model")  # fmt: skip
    p.add_argument("--json", action="store_true", help="machine-readable summary on stdout")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.set_defaults(func=_demo)


def _demo(args: argparse.Namespace) -> int:
    from rig.report import run_demo

    out = args.out or ("out/demo-independent" if args.forces == "independent" else "out/demo")
    res = run_demo(args.campaign, out, resume=args.resume, progress=not args.quiet,
                   status=status, forces=args.forces)  # fmt: skip
    if res.stopped:
        status(f"demo: stopped; run `cutlab demo --resume` to continue ({res.folder})")
        return 130
    from rig.report.demo_text import demo_lines

    print_json(res.summary()) if args.json else print_lines(demo_lines(res))
    return 0 if res.ok else 1

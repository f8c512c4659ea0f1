"""`cutlab demo` — cutlab's main job on the simulated rig: seed 003's face-milling campaign.

Runs ``configs/campaigns/facemill-ploughing.toml`` on the simulated rig (a simulated Fanuc control
on a pseudo-terminal fed by the real DNC streamer, the simulated machine cutting with the
material's true coefficients, the dynamometer's modes, the simulated DAQ and the HDF5 logger),
identifies the face-mill coefficients from the recorded runs, predicts the validation runs, and
writes the report folder. It prints the identified coefficients beside the simulator's truth.

    cutlab demo                    # -> ./out/demo/facemill-ploughing/report/report.md
    cutlab demo --json             # the same figures as JSON
"""

from __future__ import annotations

import argparse
import shutil
import time
from pathlib import Path

CAMPAIGN = "facemill-ploughing"


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    p = sub.add_parser(
        "demo",
        help="run seed 003's face-milling campaign on the simulated rig and report it",
        description=__doc__.split("\n\n")[1] if __doc__ else None,
    )
    p.add_argument("--out", default="out/demo", help="output folder (default: out/demo)")
    p.add_argument("--campaign", default=CAMPAIGN, help="campaign to run (default: %(default)s)")
    p.add_argument("--resume", action="store_true", help="keep finished runs of an earlier demo")
    p.add_argument("--json", action="store_true", help="machine-readable summary on stdout")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.set_defaults(func=_demo)


def _demo(args: argparse.Namespace) -> int:
    from analysis.errors import ConfigError
    from rig.campaign import campaign_folder, load_campaign, run_campaign
    from rig.cli._common import print_json, print_table, status
    from rig.report import write_report

    t0 = time.monotonic()
    campaign = load_campaign(args.campaign)
    if campaign.spec.campaign.rig != "sim":
        raise ConfigError(f"{campaign.path}: the demo runs on the simulated rig (rig = 'sim')")
    folder = campaign_folder(campaign, args.out)
    if folder.exists() and not args.resume:
        status(f"demo: replacing the earlier demo output in {folder}")
        shutil.rmtree(folder)
    status(
        f"demo: campaign {campaign.name}: {len(campaign.tests)} test cuts on the simulated rig "
        f"(x{campaign.spec.sim.speed:g} real time); runs -> {folder / 'runs'}"
    )
    result = run_campaign(campaign, out_root=args.out, progress=not args.quiet)
    if result.stopped:
        status(f"demo: stopped; run `cutlab demo --resume` to continue ({folder})")
        return 130
    status("demo: identifying the coefficients and writing the report ...")
    report = write_report(folder)
    fm = report.summary.get("facemill-coefficients", {})
    wall = time.monotonic() - t0
    out = {
        "campaign": campaign.name,
        "runs": len(result.runs),
        "status_counts": result.counts,
        "identification": fm.get("message"),
        "coefficients": fm.get("coefficients", []),
        "max_error_pct_seed003": fm.get("max_error_pct_seed003"),
        "validation_max_abs_error_pct": fm.get("validation_max_abs_error_pct"),
        "report": str(report.folder),
        "wall_s": round(wall, 1),
    }
    if args.json:
        print_json(out)
    else:
        print(f"Seed 003 face-milling coefficients, identified from {fm.get('identify_runs', 0)} "
              f"simulated runs, beside the simulator's truth:")  # fmt: skip
        print_table(
            [
                {"coefficient": r["coefficient"], "identified": r["identified"],
                 "truth": r.get("truth", float("nan")),
                 "error_%": r.get("error_pct", float("nan")), "std_error": r["std_error"]}
                for r in fm.get("coefficients", [])
            ]
        )  # fmt: skip
        err = fm.get("validation_max_abs_error_pct")
        if err is not None:
            print(f"validation ({fm.get('validate_runs', 0)} runs at other feeds per tooth): "
                  f"predicted mean force within {err:.2f} % of measured")  # fmt: skip
        print(f"report: {Path(report.folder) / 'report.md'}  ({wall:.0f} s)")
    ok = result.ok and bool(fm.get("success"))
    return 0 if ok else 1

"""`cutlab analyze` commands: force coefficients from runs (``forces``: how runs are read,
:mod:`analysis.identify.reading`; a catalogue's runs, :mod:`analysis.catalog`), modes from a
hammer test (``modal``), stability lobes (``stability``, :mod:`rig.cli.stability`). A fit that
the runs cannot support prints its reason and exits with status 1; bad input exits with status 2.
"""

from __future__ import annotations

import argparse

from analysis.forces_request import ForcesRequest
from analysis.modal_request import ModalRequest
from rig.cli.common import noter, print_notes, show
from rig.cli.options import (
    command,
    from_args,
    group,
    import_options,
    import_rows,
    json_row,
    model_rows,
)
from rig.terminal import Progress


def _forces(args: argparse.Namespace) -> int:
    from analysis.forces_request import fit_forces
    from analysis.identify.text import forces_lines

    req = from_args(ForcesRequest, args, "analyze forces")
    with Progress("reducing runs", "run", quiet=args.json or len(req.runs) < 2) as bar:
        out = fit_forces(req, import_options(args), bar, catalog_progress=not args.json,
                         note=noter("analyze forces"))  # fmt: skip
    print_notes("analyze forces", out, wrote=("plots",))
    return show(args.json, out, lambda: forces_lines(out), 0 if out["success"] else 1)


def _modal(args: argparse.Namespace) -> int:
    from analysis.modal import modal_lines
    from analysis.modal_request import modal_job

    out = modal_job(from_args(ModalRequest, args, "analyze modal"))
    print_notes("analyze modal", out, wrote=("plot", "stabilisation_plot", "saved"))
    return show(args.json, out, lambda: modal_lines(out))


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    from rig.cli.stability import register_stability

    psub = group(sub, "analyze", "force coefficients from runs, dynamometer modes")
    forces = model_rows(ForcesRequest, after={"rate_hz": import_rows()})
    command(psub, "forces", "fit cutting-force coefficients to recorded runs",
            [forces, json_row()], _forces)  # fmt: skip
    command(psub, "modal", "modes from an impulse-hammer record (dynamometer, tool)",
            [model_rows(ModalRequest), json_row()], _modal)  # fmt: skip
    register_stability(psub)

"""`cutlab demo`'s text: the identified face-mill coefficients beside the simulator's truth, the
validation's error, and where the report is."""

from __future__ import annotations

from pathlib import Path

from analysis.output import table_lines
from rig.report.demo import DemoResult

__all__ = ["demo_lines"]


def demo_lines(res: DemoResult) -> list[str]:
    """The demo's result as lines."""
    fm, nan = res.facemill, float("nan")
    out = [
        f"Seed 003 face-milling coefficients, identified from {fm.get('identify_runs', 0)} "
        f"simulated runs (forces: {res.force_model}), beside the simulator's truth:"
    ]
    rows = [
        {"coefficient": r["coefficient"], "identified": r["identified"],
         "truth": r.get("truth", nan), "error_%": r.get("error_pct", nan),
         "std_error": r["std_error"], "status": r.get("status", "")}
        for r in fm.get("coefficients", [])
    ]  # fmt: skip
    out += table_lines(rows, cell_max=400)
    err = fm.get("validation_max_abs_error_pct")
    if err is not None:
        out.append(
            f"validation ({fm.get('validate_runs', 0)} runs at other feeds per tooth): "
            f"predicted mean force within {err:.2f} % of measured"
        )
    assert res.report is not None  # a demo run to its end has its report (stopped: no lines)
    out.append(f"report: {Path(res.report.folder) / 'report.md'}  ({res.wall_s:.0f} s)")
    return out

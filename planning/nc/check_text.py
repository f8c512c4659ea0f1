"""What ``cutlab nc check`` prints: the summary as quantity / value rows, and the answer when
the controller of ``--dialect`` refuses a line (its reading of the program stops there)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from planning.nc.dialect import DialectProblem

__all__ = ["refused_summary", "summary_rows"]

#: summary keys that are not one row each (the bbox and rotary ranges are split, the warnings
#: and refusals go to stderr)
_NOT_ROWS = ("bbox", "warnings", "rotary_range_deg", "dialect_problems")


def summary_rows(out: Mapping[str, object]) -> list[dict[str, object]]:
    """:meth:`CheckedProgram.summary` as rows: each quantity, the rotary ranges (deg), then the
    bbox corners (mm), 4 significant digits."""
    rows: list[dict[str, object]] = [{"quantity": k, "value": v} for k, v in out.items()
                                     if k not in _NOT_ROWS and v is not None]  # fmt: skip
    rotary, bbox = out.get("rotary_range_deg", {}), out["bbox"]
    assert isinstance(rotary, Mapping) and isinstance(bbox, Mapping)
    for c, (lo, hi) in rotary.items():
        rows.append({"quantity": f"{c}_range_deg", "value": f"{lo:.4g} {hi:.4g}"})
    for end in ("min", "max"):
        xyz = " ".join(f"{c:.4g}" for c in bbox[f"{end}_mm"])
        rows.append({"quantity": f"bbox_{end}_mm", "value": xyz})
    return rows


def refused_summary(
    file: str, dialect: str, problems: Sequence[DialectProblem], reason: str
) -> dict[str, object]:
    """``nc check --json`` when the controller refuses a line: the refusals are the answer, and
    no summary is made (``summary_reason`` says why)."""
    return {"file": file, "dialect": dialect, "dialect_problems": [p.as_dict() for p in problems],
            "summary": None, "summary_reason": reason}  # fmt: skip
